"""Change detection through the bindings (docs/change.md): a known offset recovered, a box added
found, a placement of a model outside the catalogue refused."""
import math

import numpy as np
import pytest

import sonar3d


def site(box=None, offset=(0.0, 0.0, 0.0), yaw_deg=0.0, noise=0.005, seed=1, step=0.02):
    xs, ys = np.meshgrid(np.arange(-4, 4, step), np.arange(-3, 3, step))
    z = 0.2 * np.sin(0.6 * xs) * np.cos(0.45 * ys) + 0.08 * np.sin(1.7 * xs + 1.1 * ys)
    rocks = [(-2.5, 1.5, 0.15), (1.0, -1.8, 0.2), (2.8, 2.0, 0.12), (-1.0, -0.5, 0.18), (3.5, -0.8, 0.1),
             (-3.2, -2.2, 0.14)]
    for rx, ry, h in rocks:
        z += h * np.exp(-((xs - rx) ** 2 + (ys - ry) ** 2) / (2 * 0.15**2))
    if box is not None:  # (x, y, half size, height)
        bx, by, hs, h = box
        inside = (abs(xs - bx) <= hs) & (abs(ys - by) <= hs)
        z = np.where(inside, z + h, z)
    z = z + np.random.default_rng(seed).normal(0, noise, z.shape)
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    x2 = c * xs - s * ys + offset[0]
    y2 = s * xs + c * ys + offset[1]
    return np.column_stack([x2.ravel(), y2.ravel(), (z + offset[2]).ravel()]).astype(np.float32)


def test_diff_surveys_registers_and_finds_an_added_box():
    a = site(seed=1)
    b = site(box=(1.5, 1.0, 0.3, 0.4), offset=(0.2, -0.1, 0.05), yaw_deg=1.0, seed=2)
    r = sonar3d.diff_surveys(a, b, registration=sonar3d.ChangeRegistrationConfig(num_threads=2))
    assert r["format"] == "sonar3d-changes"
    T = np.array(r["T_a_b"]).reshape(4, 4)
    assert math.degrees(math.atan2(T[1, 0], T[0, 0])) == pytest.approx(-1.0, abs=0.15)
    assert len(r["regions"]) == 1
    g = r["regions"][0]
    assert g["kind"] == "raised"
    assert g["centroid"][0] == pytest.approx(1.5, abs=0.05)
    assert g["max_abs_change_m"] == pytest.approx(0.4, abs=0.05)
    assert r["change_map"].num_valid() == r["registration"]["overlap_cells"]


def test_diff_surveys_takes_b_in_a_frame_as_given():
    # B already in A's frame (what sonar3d.relocalize's map is, against A's world model): not
    # registered. With B in A's frame only the box changed; with B 0.3 m off and declared in A's
    # frame, the seabed's relief shows as change everywhere (the registration is not run).
    a = site(seed=1)
    b = site(box=(1.5, 1.0, 0.3, 0.4), seed=2)
    r = sonar3d.diff_surveys(a, b, b_in_a_frame=True,
                             registration=sonar3d.ChangeRegistrationConfig(num_threads=2))
    assert np.allclose(np.array(r["T_a_b"]).reshape(4, 4), np.eye(4))
    assert r["registration"]["method"] == "given: B in A's frame"
    assert len(r["regions"]) == 1 and r["regions"][0]["kind"] == "raised"
    off = site(box=(1.5, 1.0, 0.3, 0.4), offset=(0.3, 0.0, 0.0), seed=2)
    moved = sonar3d.diff_surveys(a, off, b_in_a_frame=True,
                                 registration=sonar3d.ChangeRegistrationConfig(num_threads=2))
    assert moved["thresholds"]["sigma_m"] > 3 * r["thresholds"]["sigma_m"]
    registered = sonar3d.diff_surveys(a, off, registration=sonar3d.ChangeRegistrationConfig(num_threads=2))
    assert np.array(registered["T_a_b"])[3] == pytest.approx(-0.3, abs=0.03)


def test_diff_surveys_refuses_a_model_outside_the_catalogue(tmp_path):
    cat = tmp_path / "cat.yaml"
    cat.write_text("models:\n  - {name: tank, reference: tank, symmetry: full}\n")
    a = site(seed=1)
    p = [{"model": "valve", "T_world_model": np.eye(4)}]
    with pytest.raises(sonar3d.Error, match="'valve' that the catalogue does not list"):
        sonar3d.diff_surveys(a, a, placements_a=p, placements_b=p, catalogue=str(cat))


def colours(points, box=None, box_rgb=(0.7, 0.08, 0.06), light=1.0, seed=3):
    """Sand everywhere, `box_rgb` on the box (x, y, half size), linear RGB scaled by `light`."""
    rgb = np.tile(np.array([0.7, 0.6, 0.3]), (len(points), 1))
    if box is not None:
        bx, by, hs = box
        inside = (abs(points[:, 0] - bx) <= hs) & (abs(points[:, 1] - by) <= hs)
        rgb[inside] = box_rgb
    rgb *= light * (1 + np.random.default_rng(seed).normal(0, 0.03, rgb.shape))
    return np.clip(rgb, 0.001, 1.0)


def test_diff_surveys_finds_a_recoloured_box():
    box = (1.5, 1.0, 0.3, 0.4)
    a = site(box=box, seed=1)
    b = site(box=box, seed=2)
    ca = (a, colours(a, box[:3], seed=4))
    cb = (b, colours(b, box[:3], box_rgb=(0.35, 0.2, 0.08), light=0.7, seed=5))
    r = sonar3d.diff_surveys(a, b, registration=sonar3d.ChangeRegistrationConfig(num_threads=2), colour_a=ca, colour_b=cb)
    assert r["regions"] == []
    c = r["colour"]
    assert c["space"] == "chromaticity"
    assert len(c["regions"]) == 1
    g = c["regions"][0]
    assert g["centroid"][0] == pytest.approx(1.5, abs=0.1)
    assert g["centroid"][1] == pytest.approx(1.0, abs=0.1)
    assert g["area_m2"] == pytest.approx(0.36, abs=0.1)
    assert g["height_change_fraction"] == 0  # the surface changed, not the geometry
    assert r["colour_change_map"].num_valid() == c["compared_cells"]
    # Without colours: no colour block.
    assert sonar3d.diff_surveys(a, b, registration=sonar3d.ChangeRegistrationConfig(num_threads=2))["colour"] is None


def test_diff_surveys_refuses_bad_colours():
    a = site(seed=1)
    good = colours(a)
    bad = good.copy()
    bad[5, 1] = np.nan
    with pytest.raises(sonar3d.Error, match="colour_b colors: row 5 has nan"):
        sonar3d.diff_surveys(a, a, colour_a=(a, good), colour_b=(a, bad))
    with pytest.raises(sonar3d.Error, match="colour_a and colour_b go together"):
        sonar3d.diff_surveys(a, a, colour_a=(a, good))
    far = a + np.array([30, 0, 0], dtype=np.float32)
    with pytest.raises(sonar3d.Error, match="the colour clouds overlap on 0 cells"):
        sonar3d.diff_surveys(a, a, colour_a=(a, good), colour_b=(far, good))


def test_change_config_is_the_commands():
    # One declaration: the command's settings, bounds checked on assignment, unknown keywords
    # refused with the fields listed.
    c = sonar3d.ChangeConfig(cell_m=0.05)
    assert c.cell_m == 0.05 and c.registration.search_m == 0.6
    assert c.colour.space == "chromaticity" and c.to_dict()["colour"]["space"] == "chromaticity"
    with pytest.raises(Exception, match="k_sigma"):
        sonar3d.ChangeConfig(k_sigma=-1)
    with pytest.raises(Exception, match="chromaticity"):
        c.colour.space = "rgb"
    a = np.zeros((10, 3), dtype=np.float32)
    with pytest.raises(Exception, match="unknown setting 'search_m'.*registration"):
        sonar3d.diff_surveys(a, a, search_m=1.0)
