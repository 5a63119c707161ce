"""Online maps through the bindings (issue 25, docs/online.md): frames fed one by one, by pose or
by navigation + image, give the batch carving's cloud; bad input is counted, not raised."""
import numpy as np
import pytest

import sonar3d

SCENE = """
seed: 7
sensor: {preset: sim-10deg, fov_deg: 30, beams: 60, r_min: 1.0, r_max: 3.0, range_bins: 100}
simulation: {elevation_step_deg: 0.05, gain: 2.0}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [0, 0, 0]}, reflectivity: 0.8}
trajectory: {period: 0.1, type: straight, start: [-2, 0, -0.6], end: [-2, 0, 0.6], spacing: 0.03}
"""


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("online")
    (root / "scene.yaml").write_text(SCENE)
    sonar3d.simulate(str(root / "scene.yaml"), str(root / "ds"))
    return sonar3d.read_dataset(str(root / "ds"))


def test_online_gives_the_batch_cloud(dataset):
    ds = dataset
    carve = sonar3d.CarveConfig(voxel_size=0.02, region=([-1, -1, -1], [1, 1, 1]))
    mapper = sonar3d.OnlineMapper(ds.spec, sonar3d.OnlineMapConfig(carve=carve))
    times = ds.timestamps
    for k in range(len(ds)):
        assert mapper.push_frame(float(times[k]), ds.frame(k), ds.pose(k)) == ""
        if k == len(ds) // 2:
            half, _ = mapper.cloud()
            assert len(half) > 0
    points, bounds = mapper.cloud()
    batch, batch_bounds, _ = sonar3d.carve(ds, carve)
    np.testing.assert_array_equal(points, batch)
    np.testing.assert_array_equal(bounds, batch_bounds)
    st = mapper.stats
    assert st["frames_used"] == len(ds) and st["points"] == len(points)
    assert st["push_ms"]["median"] > 0
    em = mapper.elevation()
    assert em.num_valid() > 0


def test_navigation_and_images_and_bad_input(dataset):
    ds = dataset
    carve = sonar3d.CarveConfig(voxel_size=0.02, region=([-1, -1, -1], [1, 1, 1]))
    mapper = sonar3d.OnlineMapper(ds.spec, sonar3d.OnlineMapConfig(carve=carve))
    nav_t, nav_T = ds.navigation
    times = ds.timestamps
    # Every image first (queued: no navigation yet), then the navigation (carved as it arrives).
    for k in range(len(ds)):
        assert mapper.push_image(float(times[k]), ds.frame(k)) == ""
    assert mapper.stats["frames_pending"] > 0
    for t, T in zip(nav_t, nav_T):
        assert mapper.push_navigation(float(t), T)
    assert not mapper.push_navigation(float(nav_t[0]), nav_T[0])  # out of order
    st = mapper.stats
    assert st["frames_used"] + st["dropped"]["queue_full"] + st["frames_pending"] == len(ds)
    assert mapper.push_image(float(times[-1]), np.zeros((3, 3), np.float32)) == "wrong_size"
    bad = ds.pose(0).copy()
    bad[0, 3] = np.nan
    assert mapper.push_frame(float(times[-1]), ds.frame(0), bad) == "bad_pose"
    st = mapper.stats
    assert st["dropped"]["wrong_size"] == 1 and st["dropped"]["bad_pose"] == 1
    assert st["navigation_rejected"] == 1
    points, _ = mapper.cloud()
    assert len(points) > 0
    with pytest.raises(sonar3d.Error, match="window_m"):
        sonar3d.OnlineMapper(ds.spec, sonar3d.OnlineMapConfig(carve=carve, window_m=0.5))
