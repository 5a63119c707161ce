"""sonar3d.survey(): the same library call as `sonar3d survey` (docs/survey.md)."""
import json

import pytest

import sonar3d

FIELD = """seed: 3
sensor:
  fov_deg: 80
  beams: 160
  r_min: 1.0
  r_max: 4.0
  range_bins: 150
  vertical_aperture_deg: 1
  T_vehicle_sonar: {rpy_deg: [0, 90, 0]}
simulation: {elevation_step_deg: 0.1}
objects:
  - {name: seabed, primitive: {type: plane, size: [20, 20]}, pose: {translation: [0, 0, 0.013]}, kind: terrain}
  - {name: box, primitive: {type: box, size: [1.0, 0.6, 0.4]}, pose: {translation: [2.0, 1.5, 0], rpy_deg: [0, 0, 30]}}
trajectory: {type: lawnmower, x: [0, 6], y: [0, 4.5], z: 3.0, line_spacing: 1.5, spacing: 0.04, period: 0.1}
"""


def test_survey_runs_resumes_and_returns_the_summary(tmp_path):
    (tmp_path / "field.yaml").write_text(FIELD)
    sonar3d.simulate(str(tmp_path / "field.yaml"), str(tmp_path / "ds"))
    config = {"map": {"region": [-1, -1, -0.6, 7, 6, 0.8], "registration": {"search_m": 0.3}}}
    calls = []
    s = sonar3d.survey(str(tmp_path / "ds"), str(tmp_path / "out"), config=config,
                       progress=lambda done, total: calls.append((done, total)))
    assert s["format"] == "sonar3d-survey"
    status = {st["name"]: st["status"] for st in s["stages"]}
    assert status == {"import": "skipped", "map": "ran", "recognize": "skipped", "world": "ran",
                      "texture": "skipped", "report": "ran"}
    mapped = s["stages"][1]
    assert mapped["figures"]["swaths"] == 4 and mapped["figures"]["points"] > 1e4
    assert mapped["seconds"] > 0 and mapped["peak_memory_mb"] > 0
    assert calls  # each stage reports, then its own steps
    on_disk = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert on_disk["stages"] == s["stages"]
    for f in ("map/merged.ply", "world/world.glb", "report.html"):
        assert (tmp_path / "out" / f).exists()
    # Resumed: nothing runs again.
    again = sonar3d.survey(tmp_path / "ds", tmp_path / "out", config=config)
    assert {st["name"]: st["status"] for st in again["stages"]}["map"] == "unchanged"
    assert {st["name"]: st["status"] for st in again["stages"]}["report"] == "unchanged"
    # The printed configuration, as a file, is the same configuration.
    text = sonar3d.survey_config(config)
    assert "search_m: 0.3" in text
    (tmp_path / "printed.yaml").write_text(text)
    assert sonar3d.survey_config(str(tmp_path / "printed.yaml")) == text
    with pytest.raises(sonar3d.Error, match="map.voxel"):
        sonar3d.survey_config({"map": {"voxel": 0.1}})
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    with pytest.raises(sonar3d.Error, match="not a sonar3d survey directory"):
        sonar3d.survey(tmp_path / "ds", tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "mine"


def test_survey_configuration_takes_the_stages_classes(tmp_path, monkeypatch):
    # A block may be the stage's own configuration class: the same keys as the YAML, the region
    # as six numbers, paths relative to the working directory.
    monkeypatch.chdir(tmp_path)
    config = {"import": {"kind": "aris",
                         "aris": sonar3d.ArisImportConfig(navigation="nav.csv",
                                                          vertical_aperture_deg=10,
                                                          mount=[0, 0, 0, 0, 90, 0]),
                         "rosbag": {"sonar_topic": "/sonar"}},
              "map": sonar3d.MapSurveyConfig(method="drift",
                                             region=((-1, -1, -1), (1, 1, 1)))}
    text = sonar3d.survey_config(config)
    assert f'navigation: "{tmp_path / "nav.csv"}"' in text
    assert "vertical_aperture_deg: 10" in text
    assert "mount: [0, 0, 0, 0, 90, 0]" in text
    assert 'sonar_topic: "/sonar"' in text
    assert "region: [-1, -1, -1, 1, 1, 1]" in text
    assert "method: drift" in text
    (tmp_path / "printed.yaml").write_text(text)
    assert sonar3d.survey_config(str(tmp_path / "printed.yaml")) == text
    # The earlier flat keys name where they live now.
    with pytest.raises(sonar3d.Error, match="import.aris.navigation, import.oculus.navigation"):
        sonar3d.survey_config({"import": {"nav": "nav.csv"}})
