"""Core types through the bindings: sensor, projector, poses, clouds, meshes."""
import numpy as np
import pytest

import sonar3d


def test_module_has_docstrings():
    assert "sonar" in sonar3d.__doc__
    for name in ["read_dataset", "write_dataset", "simulate", "denoise", "evaluate",
                 "import_holoocean", "import_frames", "import_oculus", "import_aris", "import_rosbag",
                 "read_navigation"]:
        assert getattr(sonar3d, name).__doc__, name


def test_presets_and_spec_fields():
    assert "p900-130" in sonar3d.SonarSpec.presets()
    spec = sonar3d.SonarSpec.preset("sim-10deg")
    assert spec.beams == 300 and spec.range_bins == 200
    assert spec.range_resolution == pytest.approx(0.02)
    assert spec.range_of_bin(0) == pytest.approx(1.01)
    assert spec.bin_of_range(1.019) == 0
    assert spec.vertical_aperture == pytest.approx(np.radians(10))
    assert spec.beam_of_bearing(0.0) in (149, 150)
    assert "r_min" in spec.to_yaml()
    with pytest.raises(sonar3d.Error, match="unknown sonar preset"):
        sonar3d.SonarSpec.preset("nope")


def test_bearings_are_a_read_only_view_without_copy():
    spec = sonar3d.SonarSpec.preset("sim-10deg")
    b = spec.bearings
    assert b.dtype == np.float64 and b.shape == (300,)
    assert not b.flags.owndata and b.base is not None
    assert not b.flags.writeable
    spec.bearings = np.linspace(-0.5, 0.5, 11)
    assert spec.beams == 11
    spec.beam_pattern = "flat"
    assert spec.beam_pattern == "flat"
    with pytest.raises(sonar3d.Error):
        spec.beam_pattern = "gaussian"


def test_spec_validate_names_the_field():
    spec = sonar3d.SonarSpec.preset("sim-10deg")
    spec.r_max = 0.5
    with pytest.raises(sonar3d.Error, match="r_max"):
        spec.validate()


def test_polar_round_trip():
    rng = np.random.default_rng(1)
    r = rng.uniform(0.5, 7, 100)
    b = rng.uniform(-1, 1, 100)
    e = rng.uniform(-0.3, 0.3, 100)
    p = sonar3d.polar_to_sonar(r, b, e)
    assert p.shape == (100, 3)
    np.testing.assert_allclose(sonar3d.sonar_to_polar(p), np.stack([r, b, e], 1), atol=1e-12)
    # +y is left: a positive bearing points to +y.
    assert sonar3d.polar_to_sonar(1.0, 0.5, 0.0)[1] > 0


def pose(yaw, t):
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = t
    return T


def test_tum_round_trip_and_interpolation(tmp_path):
    times = np.array([0.0, 1.0, 2.0])
    poses = np.stack([pose(0.0, [0, 0, 0]), pose(0.5, [1, 0, 0]), pose(1.0, [2, 2, 0])])
    path = str(tmp_path / "nav.tum")
    sonar3d.write_tum(path, times, poses)
    t2, p2 = sonar3d.read_tum(path)
    np.testing.assert_allclose(t2, times)
    np.testing.assert_allclose(p2, poses, atol=1e-12)
    mid = sonar3d.interpolate_poses(times, poses, [0.5, 1.5])
    np.testing.assert_allclose(mid[0], pose(0.25, [0.5, 0, 0]), atol=1e-12)
    np.testing.assert_allclose(mid[1][:3, 3], [1.5, 1, 0], atol=1e-12)
    with pytest.raises(sonar3d.Error, match="outside the navigation span"):
        sonar3d.interpolate_poses(times, poses, [2.5])
    bad = poses.copy()
    bad[1, :3, :3] *= 2
    with pytest.raises(sonar3d.Error, match="rigid"):
        sonar3d.write_tum(path, times, bad)


def test_ply_round_trip_zero_copy(tmp_path):
    rng = np.random.default_rng(2)
    pts = rng.normal(size=(500, 3)).astype(np.float32)
    inten = rng.uniform(size=500).astype(np.float32)
    path = str(tmp_path / "c.ply")
    sonar3d.write_ply(path, pts, inten)
    p2, i2 = sonar3d.read_ply(path)
    assert p2.dtype == np.float32 and p2.shape == (500, 3)
    assert not p2.flags.owndata  # the library's vector, not a copy
    np.testing.assert_array_equal(p2, pts)
    np.testing.assert_array_equal(i2, inten)
    sonar3d.write_ply(path, pts, binary=False)
    assert sonar3d.read_ply(path)[1] is None
    with pytest.raises(sonar3d.Error, match="N×3"):
        sonar3d.write_ply(path, pts[:, :2])


def test_meshes(tmp_path):
    sphere = sonar3d.make_sphere(0.5, 32)
    assert sphere.surface_area() == pytest.approx(np.pi, rel=0.02)
    v = sphere.vertices
    assert v.shape[1] == 3 and not v.flags.writeable and v.base is not None
    lo, hi = sphere.bounding_box()
    np.testing.assert_allclose(lo, [-0.5] * 3, atol=1e-6)
    moved = sphere.transformed(pose(0.0, [1, 2, 3]))
    np.testing.assert_allclose(moved.bounding_box()[0], [0.5, 1.5, 2.5], atol=1e-6)
    path = str(tmp_path / "s.ply")
    sonar3d.save_mesh(path, moved)
    again = sonar3d.load_mesh(path)
    assert len(again) == len(sphere)
    tri = sonar3d.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    assert tri.surface_area() == pytest.approx(0.5)
    with pytest.raises(sonar3d.Error, match="out of range"):
        sonar3d.Mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    assert set(sonar3d.reference_object_names()) >= {"sphere", "tank", "pillar", "riser"}


def test_read_ply_all_fields(tmp_path):
    # A cloud as `sonar3d texture` writes it: intensity, colours and a per-point scalar.
    path = tmp_path / "coloured.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                    "property float z\nproperty float intensity\nproperty uchar red\n"
                    "property uchar green\nproperty uchar blue\nproperty float views\n"
                    "end_header\n0 1 2 0.5 10 20 30 3\n4 5 6 0.25 200 100 0 0\n")
    pts, inten = sonar3d.read_ply(str(path))  # the tuple, as before
    assert pts.shape == (2, 3) and inten.tolist() == [0.5, 0.25]
    d = sonar3d.read_ply(str(path), all_fields=True)
    np.testing.assert_array_equal(d["points"], [[0, 1, 2], [4, 5, 6]])
    assert d["intensity"].tolist() == [0.5, 0.25]
    assert d["colors"].dtype == np.uint8
    assert d["colors"].tolist() == [[10, 20, 30], [200, 100, 0]]
    assert d["properties"]["views"].tolist() == [3.0, 0.0]
    plain = tmp_path / "plain.ply"
    sonar3d.write_ply(str(plain), pts)
    d = sonar3d.read_ply(str(plain), all_fields=True)
    assert d["intensity"] is None and d["colors"] is None and d["properties"] == {}
