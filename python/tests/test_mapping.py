"""Field mapping through the bindings: elevation maps, GeoTIFF round trip, swath registration."""
import json
import math


import numpy as np
import pytest

import sonar3d


def terrain(x, y):
    return 0.25 * np.sin(0.7 * x) * np.cos(0.5 * y) + 0.1 * np.sin(1.9 * x + 1.3 * y)


def seabed(offset=(0.0, 0.0, 0.0), step=0.01):
    xs, ys = np.meshgrid(np.arange(0, 4, step) + step / 2, np.arange(0, 3, step) + step / 2)
    pts = np.column_stack([xs.ravel(), ys.ravel(), terrain(xs, ys).ravel()])
    return (pts + np.asarray(offset)).astype(np.float32)


def test_elevation_map_keeps_the_highest_point_and_no_data():
    pts = np.float32([[0.01, 0.01, -1.0], [0.015, 0.005, -0.5], [0.09, 0.01, 2.0]])
    m = sonar3d.elevation_map(pts, cell_m=0.02)
    assert (m.rows, m.cols) == (1, 5)
    assert m.z[0, 0] == pytest.approx(-0.5)
    assert np.isnan(m.z[0, 1:4]).all()
    assert m.num_valid() == 2
    assert "cell_m=0.02" in repr(m)
    with pytest.raises(sonar3d.Error, match="cell_m"):
        sonar3d.elevation_map(pts, cell_m=0.0)


def test_geotiff_round_trip(tmp_path):
    m = sonar3d.elevation_map(seabed(), cell_m=0.02)
    path = str(tmp_path / "m.tif")
    sonar3d.write_elevation_geotiff(path, m, uint16_step_m=0.001)
    r = sonar3d.read_elevation_geotiff(path)
    assert (r.rows, r.cols) == (m.rows, m.cols)
    assert np.allclose(r.origin_xy, m.origin_xy)
    assert np.nanmax(np.abs(r.z - m.z)) <= 0.0005 + 1e-6


def test_registration_recovers_a_known_shift():
    a = sonar3d.elevation_map(seabed(), cell_m=0.02)
    b = sonar3d.elevation_map(seabed((0.08, -0.06, 0.03)), cell_m=0.02)
    cfg = sonar3d.SwathRegistrationConfig(search_m=0.2)
    assert "coarse_factor=4" in repr(cfg)
    tie = sonar3d.register_elevation_maps(a, b, cfg)
    assert tie.t[0] == pytest.approx(-0.08, abs=0.005)
    assert tie.t[1] == pytest.approx(0.06, abs=0.005)
    assert tie.t[2] == pytest.approx(-0.03, abs=0.003)
    assert tie.confidence > 0.5
    with pytest.raises(AttributeError):
        sonar3d.SwathRegistrationConfig(serach_m=0.2)  # a misspelt keyword is an error


FIELD = """seed: 3
navigation_error: {velocity_scale: 0.02, heading_bias_deg: 0.3, bias_walk: 0.002}
sensor: {fov_deg: 80, beams: 160, r_min: 1.0, r_max: 4.0, range_bins: 150,
         vertical_aperture_deg: 1, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}
simulation: {elevation_step_deg: 0.1}
objects:
  - {name: seabed, primitive: {type: plane, size: [20, 20]}, pose: {translation: [0, 0, 0.013]}, kind: terrain}
  - {name: box, primitive: {type: box, size: [1.0, 0.6, 0.4]}, pose: {translation: [2.0, 1.5, 0], rpy_deg: [0, 0, 30]}}
  - {name: pipe, pipeline: {from: [3, 2, 0.013], to: [7, 3.5, 0.013], radius: 0.15, burial: 0.3}}
  - {name: rock, primitive: {type: sphere, radius: 0.3}, pose: {translation: [4.5, 3.2, -0.1]}}
trajectory: {type: lawnmower, x: [0, 6], y: [0, 4.5], z: 3.0, line_spacing: 1.5, spacing: 0.04, period: 0.1}
"""


def test_map_survey_with_the_drift_method(tmp_path):
    (tmp_path / "field.yaml").write_text(FIELD)
    sonar3d.simulate(str(tmp_path / "field.yaml"), str(tmp_path / "ds"))
    ds = sonar3d.read_dataset(str(tmp_path / "ds"))
    cfg = sonar3d.MapSurveyConfig(method="drift", piece_m=2.0)
    cfg.registration.search_m = 0.3
    r = sonar3d.map_survey(ds, str(tmp_path / "map"), config=cfg,
                           region=((-1, -1, -0.6), (7, 6, 0.8)))
    assert len(r["offsets"]) == 4 and len(r["rates"]) == 4
    assert np.allclose(r["offsets"][0], 0.0)  # the gauge: exact where swath 0 starts
    assert any(np.linalg.norm(rate) > 0 for rate in r["rates"])
    kinds = {s["name"]: s["kind"] for s in r["structures"]}
    assert kinds == {"box": "structure", "pipe": "pipeline", "rock": "structure"}
    for s in r["structures"]:
        assert s["after"]["median_error"] < 0.05
    # The CLI's summary.json, as the CLI wrote it.
    assert r["summary"] == json.loads((tmp_path / "map" / "summary.json").read_text())
    # The configuration is the command's: its --print-config keys and defaults.
    assert sonar3d.MapSurveyConfig().cell_m == 0.02
    assert cfg.to_dict()["split"]["turn_threshold_deg"] == 30
    with pytest.raises(sonar3d.Error, match="consecutive, global or drift"):
        sonar3d.map_survey(ds, str(tmp_path / "map2"), method="sideways")
    with pytest.raises(sonar3d.Error, match="unknown setting 'resolution'"):
        sonar3d.map_survey(ds, str(tmp_path / "map2"), resolution=0.05)
    assert not (tmp_path / "map2").exists()


def test_map_survey_with_fixes(tmp_path):
    # Absolute fixes (issue 26): fixes of 10 cm every 2 s from the true navigation, one 3 m off,
    # place the map and the outlier is reported. (Fixes of 2 cm would be rejected by the dozen
    # here: the fast bias walk leaves the navigation off the global method's model by more.)
    (tmp_path / "field.yaml").write_text(FIELD)
    sonar3d.simulate(str(tmp_path / "field.yaml"), str(tmp_path / "ds"))
    ds = sonar3d.read_dataset(str(tmp_path / "ds"))
    truth = np.loadtxt(str(tmp_path / "ds" / "truth" / "navigation.tum"))
    rng = np.random.default_rng(4)
    times = np.arange(1.0, truth[-1, 0], 2.0)
    lines = ["time_s,x_m,y_m,sigma_m"]
    for k, t in enumerate(times):
        x = np.interp(t, truth[:, 0], truth[:, 1]) + rng.normal(0, 0.1)
        y = np.interp(t, truth[:, 0], truth[:, 2]) + rng.normal(0, 0.1)
        lines.append(f"{t},{x + (3.0 if k == 10 else 0.0)},{y},0.1")
    (tmp_path / "fixes.csv").write_text("\n".join(lines) + "\n")
    cfg = sonar3d.MapSurveyConfig(region=((-1, -1, -0.6), (7, 6, 0.8)))
    cfg.registration.search_m = 0.3
    r = sonar3d.map_survey(ds, str(tmp_path / "map"), config=cfg, fixes=str(tmp_path / "fixes.csv"))
    assert r["fixes"]["given"] == len(times)
    assert [f["time_s"] for f in r["fixes"]["rejected"]] == [times[10]]
    assert r["navigation_model"]["estimated"]
    assert r["navigation_model"]["scale_error_sigma"] > 0
    with pytest.raises(sonar3d.Error, match="bad.csv:2"):
        (tmp_path / "bad.csv").write_text("time_s,x_m,y_m,sigma_m\n1,2,3,nan\n")
        sonar3d.map_survey(ds, str(tmp_path / "map3"), fixes=str(tmp_path / "bad.csv"))
