"""Simulation, denoising and evaluation through the bindings."""
import numpy as np
import pytest

import sonar3d


def looking_at_sphere(z):
    T = np.eye(4)
    T[:3, 3] = [-2.0, 0.0, z]
    return T


def test_render_sees_the_sphere_at_its_range(small_spec):
    sphere = sonar3d.make_sphere(0.5, 48)
    sim = sonar3d.Simulator([{"mesh": sphere, "reflectivity": 0.8}], small_spec,
                            sonar3d.SimulatorConfig(elevation_step=np.radians(0.05)))
    img = sim.render(looking_at_sphere(0.0), seed=1)
    assert img.shape == (80, 48) and img.dtype == np.float32
    assert not img.flags.owndata
    rows, cols = np.nonzero(img)
    assert len(rows) > 0
    # The front of the sphere is 1.5 m away, on the boresight.
    assert small_spec.range_of_bin(rows.min()) == pytest.approx(1.5, abs=0.03)
    assert abs(small_spec.bearings[cols[np.argmax(img[rows, cols])]]) < np.radians(8)
    stack = sim.render_many(np.stack([looking_at_sphere(z) for z in (0.0, 0.1)]), seed=1)
    assert stack.shape == (2, 80, 48)
    np.testing.assert_array_equal(stack[0], img)
    with pytest.raises(sonar3d.Error, match="no object"):
        sonar3d.Simulator([], small_spec)
    with pytest.raises(AttributeError):
        sonar3d.SimulatorConfig(no_such_field=1)


def test_denoise_z_test_and_threshold():
    rng = np.random.default_rng(4)
    mean = np.full((20, 10), 0.1, np.float32)
    std = np.full((20, 10), 0.01, np.float32)
    img = sonar3d.add_noise(np.zeros((20, 10), np.float32), mean, std, seed=3)
    img[5, 5] = 0.5
    out = sonar3d.denoise(img, mean, std)
    assert out[5, 5] == pytest.approx(0.4)  # mean subtracted
    assert np.count_nonzero(out) <= 2  # noise fails the Z-test (T = 3)
    kept = sonar3d.denoise(img, config=sonar3d.DenoiseConfig(static_threshold=0.3))
    assert np.count_nonzero(kept) == 1
    assert img[5, 5] == pytest.approx(0.5), "the input is not modified"
    with pytest.raises(sonar3d.Error, match="both"):
        sonar3d.denoise(img, mean)


def test_evaluate_points_on_and_off_the_surface():
    sphere = sonar3d.make_sphere(0.5, 64)
    rng = np.random.default_rng(6)
    d = rng.normal(size=(20000, 3))
    on = (0.5 * d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    r = sonar3d.evaluate(on, sphere)
    assert r["median_error"] < 0.002
    assert r["coverage"] > 0.95 and r["outliers"] == 0
    off = on * 1.5  # 25 cm off the surface
    r2 = sonar3d.evaluate(off, (sphere.vertices, sphere.triangles),
                          sonar3d.EvalConfig(outlier_radius=0.1))
    assert r2["outliers"] == 1.0 and r2["coverage"] == 0.0
    dist = sonar3d.point_to_mesh_distance(off[:10], sphere)
    np.testing.assert_allclose(dist, 0.25, atol=0.002)


def test_evaluate_against_a_mesh_file(tmp_path):
    path = tmp_path / "box.obj"
    sonar3d.save_mesh(str(path), sonar3d.make_box(1, 1, 1))
    pts = np.array([[0.5, 0, 0], [0.6, 0, 0]], np.float32)
    for mesh in (str(path), path):
        np.testing.assert_allclose(sonar3d.point_to_mesh_distance(pts, mesh), [0, 0.1], atol=1e-6)
    with pytest.raises(sonar3d.Error):
        sonar3d.evaluate(pts, str(tmp_path / "missing.obj"))


SCENE = """
seed: 3
sensor: {preset: sim-10deg, fov_deg: 30, beams: 60, r_min: 1.0, r_max: 3.0, range_bins: 100}
simulation: {elevation_step_deg: 0.05, gain: 2.0}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.5}, pose: {translation: [0, 0, 0]}, reflectivity: 0.8}
trajectory: {period: 0.1, type: straight, start: [-2, 0, -0.1], end: [-2, 0, 0.1], spacing: 0.05}
"""


def test_simulate_scene_then_evaluate_dataset(tmp_path):
    scene = tmp_path / "scene.yaml"
    scene.write_text(SCENE)
    stats = sonar3d.simulate(str(scene), str(tmp_path / "ds"))
    assert stats["frames"] == 5
    ds = sonar3d.read_dataset(str(tmp_path / "ds"))
    assert len(ds) == 5 and ds.has_truth
    truth = ds.truth()
    assert truth[0]["name"] == "ball"
    # Every lit pixel, placed at elevation 0, is within the aperture's reach of the sphere.
    pts = []
    for k in range(len(ds)):
        rows, cols = np.nonzero(ds.frame(k))
        pts.append(sonar3d.pixel_to_world(ds.spec, ds.pose(k), rows, cols, 0.0))
    pts = np.concatenate(pts).astype(np.float32)
    per = sonar3d.evaluate_dataset(pts, ds)
    assert set(per) == {"ball", "all"}
    assert per["all"]["num_points"] == len(pts)
    assert per["ball"]["median_error"] < 0.05
