"""The package as a user meets it: its version, and configs that print every field."""
import os
import re

import numpy as np

import sonar3d

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def test_version_is_the_projects():
    with open(os.path.join(ROOT, "CMakeLists.txt"), encoding="utf-8") as f:
        version = re.search(r"project\(sonar3d VERSION ([0-9.]+)", f.read()).group(1)
    assert sonar3d.__version__ == version


def fields(cls):
    return [n for n, v in vars(cls).items() if isinstance(v, property) and not n.startswith("_")]


def test_configs_print_every_field_with_its_value():
    configs = [sonar3d.DenoiseConfig(z_threshold=2.5), sonar3d.CarveConfig(voxel_size=0.03),
               sonar3d.DeconvConfig(beam="flat"), sonar3d.SimulatorConfig(rays_per_beam=3),
               sonar3d.EvalConfig(seed=7), sonar3d.SonarSpec.preset("sim-10deg")]
    for c in configs:
        text = repr(c)
        assert text.startswith(type(c).__name__ + "("), text
        names = fields(type(c))
        assert len(names) >= 4, type(c)
        for name in names:
            assert name + "=" in text, (name, text)
        assert str(c) == text
    assert "z_threshold=2.5" in repr(configs[0])
    assert "voxel_size=0.03" in repr(configs[1]) and "denoise=DenoiseConfig(" in repr(configs[1])
    assert "beam='flat'" in repr(configs[2])
    assert "rays_per_beam=3" in repr(configs[3])
    assert "seed=7" in repr(configs[4])
    # Large arrays are summarised, small ones shown.
    assert "bearings=<array shape (300,) float64>" in repr(configs[5])
    cfg = sonar3d.CarveConfig(region=([0, 0, 0], [1, 2, 3]))
    assert "region=(array([0., 0., 0.]), array([1., 2., 3.]))" in repr(cfg)
    assert np.allclose(cfg.region[1], [1, 2, 3])
