"""Reconstruction through the bindings: carving (ch. 4) and deconvolution (ch. 5) of a simulated
sphere seen by a vertical pass. Skipped when the build has no such method."""
import numpy as np
import pytest

import sonar3d

SCENE = """
seed: 5
sensor: {preset: sim-10deg, fov_deg: 30, beams: 75, r_min: 1.0, r_max: 3.0, range_bins: 100}
simulation: {elevation_step_deg: 0.02, gain: 2.0}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.5}, pose: {translation: [0, 0, 0]}, reflectivity: 0.8}
trajectory: {period: 0.1, type: straight, start: [-2, 0, -0.7], end: [-2, 0, 0.7], spacing: 0.02}
"""


@pytest.fixture(scope="module")
def sphere_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("recon")
    (root / "scene.yaml").write_text(SCENE)
    sonar3d.simulate(str(root / "scene.yaml"), str(root / "ds"))
    return str(root / "ds")


@pytest.mark.skipif(not hasattr(sonar3d, "carve"), reason="carving is not in this build")
def test_carve_a_sphere(sphere_dataset):
    ds = sonar3d.read_dataset(sphere_dataset)
    cfg = sonar3d.CarveConfig(voxel_size=0.02, region=([-1, -1, -1], [1, 1, 1]))
    assert cfg.region is not None
    points, bounds = sonar3d.carve(ds, cfg)
    assert points.shape[1] == 3 and len(points) > 100
    assert bounds.shape == (len(points),)
    r = sonar3d.evaluate_dataset(points, sphere_dataset)["ball"]
    assert r["median_error"] < 0.03
    # The online interface gives the same cloud.
    carver = sonar3d.Carver(ds.spec, cfg)
    for k in range(len(ds)):
        carver.integrate(ds.frame(k), ds.pose(k))
    p2, _ = carver.finalize()
    assert carver.frames == len(ds)
    assert abs(len(p2) - len(points)) <= 0.01 * len(points)


@pytest.mark.skipif(not hasattr(sonar3d, "deconvolve"), reason="deconvolution is not in this build")
def test_deconvolve_a_sphere(sphere_dataset):
    ds = sonar3d.read_dataset(sphere_dataset)
    points, b, report = sonar3d.deconvolve(ds, sonar3d.DeconvConfig(beam="sinc"))
    assert len(points) > 100 and len(b) == len(points)
    assert report["frames"] == len(ds)
    r = sonar3d.evaluate_dataset(points, sphere_dataset)["ball"]
    assert r["median_error"] < 0.03


@pytest.mark.skipif(not hasattr(sonar3d, "reconstruct"), reason="reconstruct is not in this build")
def test_reconstruct_region_applies_to_every_method(sphere_dataset):
    ds = sonar3d.read_dataset(sphere_dataset)
    upper = ([-1.0, -1.0, 0.0], [1.0, 1.0, 1.0])  # the sphere's upper half only
    for method in ("carve", "deconv"):
        whole, _, _ = sonar3d.reconstruct(ds, method)
        cut, intensity, info = sonar3d.reconstruct(ds, method, region=upper)
        assert len(cut) > 50, method
        assert len(cut) < len(whole), method
        assert cut[:, 2].min() >= 0.0, method
        assert intensity is not None and len(intensity) == len(cut)
        assert info["seconds"] > 0
    with pytest.raises(Exception, match="region"):
        sonar3d.reconstruct(ds, "deconv", region=([0, 0, 0], [1, 1, 0]))
    carver = sonar3d.Carver(ds.spec, sonar3d.CarveConfig(voxel_size=0.02))
    for k in range(len(ds)):
        carver.integrate(ds.frame(k), ds.pose(k))
    carver.finalize()
    # 2 cm steps, a 10° aperture at 2 m: every point is seen by many frames, the filter holds.
    assert carver.stats["min_observations_used"] == 2
    assert carver.stats["views_per_scatterer"] > 5
