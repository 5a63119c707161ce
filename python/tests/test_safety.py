"""The Python module keeps the CLI's promise: it never replaces what sonar3d did not write, and
replaces a sonar3d dataset only when asked (overwrite=True)."""
import pytest

import sonar3d

SCENE = """
seed: 1
sensor: {preset: sim-10deg, fov_deg: 20, beams: 20, r_min: 1.0, r_max: 3.0, range_bins: 40}
simulation: {elevation_step_deg: 0.5}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.5}, pose: {translation: [0, 0, 0]}, reflectivity: 0.8}
trajectory: {period: 0.1, type: straight, start: [-2, 0, -0.1], end: [-2, 0, 0.1], spacing: 0.05}
"""


def test_simulate_replaces_only_its_own_outputs_and_only_when_asked(tmp_path):
    scene = tmp_path / "scene.yaml"
    scene.write_text(SCENE)
    out = tmp_path / "ds"
    sonar3d.simulate(str(scene), str(out))
    with pytest.raises(sonar3d.Error, match="overwrite"):
        sonar3d.simulate(str(scene), str(out))
    sonar3d.simulate(str(scene), str(out), overwrite=True)
    assert (out / "sonar.yaml").exists()
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "holiday.jpg").write_bytes(b"not sonar data")
    with pytest.raises(sonar3d.Error, match="photos"):
        sonar3d.simulate(str(scene), str(foreign), overwrite=True)
    assert (foreign / "holiday.jpg").read_bytes() == b"not sonar data"


def test_an_import_never_writes_over_its_source(tmp_path):
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "Config.json").write_text("{}")
    with pytest.raises(sonar3d.Error):
        sonar3d.import_holoocean(str(rec), str(rec), overwrite=True)
    assert (rec / "Config.json").read_text() == "{}"
