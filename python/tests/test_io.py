"""Datasets and imports through the bindings."""
import os
import pickle

import numpy as np
import pytest

import sonar3d
from conftest import write_holoocean


def yaw_pose(yaw, t):
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = t
    return T


def test_write_read_dataset_round_trip(tmp_path, small_spec):
    rng = np.random.default_rng(3)
    images = rng.uniform(0, 1, (4, 80, 48)).astype(np.float32)
    poses = np.stack([yaw_pose(0.1 * k, [k, 0, -1]) for k in range(4)])
    mount = yaw_pose(0.3, [0.2, 0, 0])
    small_spec.T_vehicle_sonar = mount
    path = str(tmp_path / "ds")
    sonar3d.write_dataset(path, small_spec, images, poses=poses, timestamps=[0, 0.5, 1, 1.5],
                          format="tiff", noise_mean=np.full((80, 48), 0.01),
                          noise_std=np.full((80, 48), 0.02))
    ds = sonar3d.read_dataset(path)
    assert len(ds) == 4
    np.testing.assert_allclose(ds.timestamps, [0, 0.5, 1, 1.5])
    np.testing.assert_allclose(ds.spec.T_vehicle_sonar, mount, atol=1e-12)
    np.testing.assert_allclose(ds.poses(), poses, atol=1e-9)
    np.testing.assert_allclose(ds.pose(2), poses[2], atol=1e-9)
    f = ds.frame(1)
    assert f.dtype == np.float32 and f.shape == (80, 48)
    assert not f.flags.owndata and f.base is not None  # moved from the library, no copy
    np.testing.assert_array_equal(f, images[1])
    np.testing.assert_array_equal(ds.frame(-1), images[3])
    np.testing.assert_array_equal(ds.frames([0, 2]), images[[0, 2]])
    np.testing.assert_array_equal(ds.frames(), images)
    mean = ds.noise_mean
    assert mean.shape == (80, 48) and not mean.flags.writeable and mean.base is not None
    assert float(ds.noise_std[5, 5]) == pytest.approx(0.02)
    times, nav = ds.navigation
    np.testing.assert_allclose(nav[0] @ mount, poses[0], atol=1e-9)
    assert not ds.has_truth
    spec = ds.spec
    spec.r_min = 0.0  # a copy: the dataset keeps its sensor
    assert ds.spec.r_min == small_spec.r_min


def test_png_quantises_to_bit_depth(tmp_path, small_spec):
    img = np.full((80, 48), 0.123456, np.float32)
    path = str(tmp_path / "ds")
    sonar3d.write_dataset(path, small_spec, [img], poses=[np.eye(4)])
    got = sonar3d.read_dataset(path).frame(0)
    assert abs(got[0, 0] - 0.123456) <= 0.51 / 65535


def test_dataset_errors_are_sonar3d_errors(tmp_path, small_spec):
    with pytest.raises(sonar3d.Error, match="not a directory"):
        sonar3d.read_dataset(str(tmp_path / "none"))
    with pytest.raises(sonar3d.Error, match="one pose per image"):
        sonar3d.write_dataset(str(tmp_path / "a"), small_spec, np.zeros((2, 80, 48)),
                              poses=[np.eye(4)])
    with pytest.raises(sonar3d.Error, match="frame 0 is 10×10"):
        sonar3d.write_dataset(str(tmp_path / "b"), small_spec, [np.zeros((10, 10))],
                              poses=[np.eye(4)])
    assert not os.path.exists(tmp_path / "b"), "a failed write leaves nothing"
    with pytest.raises(sonar3d.Error, match="rigid"):
        sonar3d.write_dataset(str(tmp_path / "c"), small_spec, [np.zeros((80, 48))],
                              poses=[2 * np.eye(4)])
    with pytest.raises(sonar3d.Error, match="format"):
        sonar3d.write_dataset(str(tmp_path / "d"), small_spec, [np.zeros((80, 48))],
                              poses=[np.eye(4)], format="jpg")


# ---------------------------------------------------------------- HoloOcean

RB, AB, RMIN, RMAX, AZ, EL = 100, 64, 0.5, 4.5, 60.0, 12.0
DR, DA = (RMAX - RMIN) / RB, np.radians(AZ) / AB


def holo_pose(k):
    T = yaw_pose(0.4 + 0.3 * k, [-18 + k, 16, -22])
    pitch = 0.3
    Ry = np.array([[np.cos(pitch), 0, np.sin(pitch)], [0, 1, 0], [-np.sin(pitch), 0, np.cos(pitch)]])
    T[:3, :3] = T[:3, :3] @ Ry
    return T


def their_point(pose, r, az, el):
    """neusis: p = (r cos az cos el, r sin az cos el, r sin el), then PoseSensor."""
    p = np.array([r * np.cos(az) * np.cos(el), r * np.sin(az) * np.cos(el), r * np.sin(el), 1])
    return (pose @ p)[:3]


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
@pytest.mark.parametrize("bins", ["sample", "cell"])
def test_import_holoocean_maps_a_placed_point_back(tmp_path, dtype, bins):
    rng = np.random.default_rng(5)
    images, poses, placed = [], [], []
    for k in range(3):
        pose = holo_pose(k)
        img = np.zeros((RB, AB), dtype)
        for q in range(3):
            r, az, el = rng.uniform(1, 4), np.radians(rng.uniform(-25, 25)), np.radians(
                rng.uniform(-5, 5))
            fi, fj = (r - RMIN) / DR, (az + np.radians(AZ) / 2) / DA
            i, j = (int(round(fi)), int(round(fj))) if bins == "sample" else (int(fi), int(fj))
            img[i, j] = 200
            placed.append((k, i, j, their_point(pose, r, az, el), el, r))
        images.append(img)
        poses.append(pose)
    src = write_holoocean(str(tmp_path / "holo"), images, poses, RB, AB, RMIN, RMAX, AZ, EL)
    out = str(tmp_path / "ds")
    res = sonar3d.import_holoocean(src, out, bins=bins)
    assert res["frames"] == 3 and res["dtype"] == np.dtype(dtype).name
    assert res["warnings"] == []
    ds = sonar3d.read_dataset(out)
    assert ds.spec.beam_pattern == "flat"
    for k, i, j, p_world, el, r in placed:
        assert ds.frame(k)[i, j] > 0
        back = sonar3d.pixel_to_world(ds.spec, ds.pose(k), i, j, el)
        assert np.linalg.norm(back - p_world) <= np.hypot(DR / 2, r * DA / 2) + 1e-4
    lit = sum(int((ds.frame(k) > 0).sum()) for k in range(3))
    assert lit == len(placed)


def test_import_holoocean_sample_pixel_is_exact(tmp_path):
    pose = holo_pose(1)
    img = np.zeros((RB, AB), np.float32)
    img[37, 11] = 0.75
    src = write_holoocean(str(tmp_path / "holo"), [img], [pose], RB, AB, RMIN, RMAX, AZ, EL)
    sonar3d.import_holoocean(src, str(tmp_path / "ds"))
    ds = sonar3d.read_dataset(str(tmp_path / "ds"))
    theirs = their_point(pose, RMIN + 37 * DR, -np.radians(AZ) / 2 + 11 * DA, 0.05)
    ours = sonar3d.pixel_to_world(ds.spec, ds.pose(0), 37, 11, 0.05)
    assert np.linalg.norm(ours - theirs) < 5e-5


def test_import_holoocean_bad_pickles(tmp_path):
    good = np.zeros((RB, AB), np.float32)
    src = write_holoocean(str(tmp_path / "holo"), [good, good], [np.eye(4), np.eye(4)],
                          RB, AB, RMIN, RMAX)
    bad = os.path.join(src, "Data", "001.pkl")
    out = str(tmp_path / "ds")
    cases = [
        ({"ImagingSonar": good}, "key 'PoseSensor' is missing"),
        ({"ImagingSonar": good.T, "PoseSensor": np.eye(4)}, "64×100"),
        ({"ImagingSonar": good.astype(np.int32), "PoseSensor": np.eye(4)}, "dtype int32"),
        ({"ImagingSonar": good, "PoseSensor": np.diag([1.0, 1, 1.1, 1])}, "not a rigid"),
    ]
    for content, message in cases:
        with open(bad, "wb") as f:
            pickle.dump(content, f)
        with pytest.raises(sonar3d.Error, match=message) as e:
            sonar3d.import_holoocean(src, out)
        assert "001.pkl" in str(e.value)
        assert not os.path.exists(out)
    with open(bad, "wb") as f:
        f.write(pickle.dumps({"ImagingSonar": good, "PoseSensor": np.eye(4)})[:50])
    with pytest.raises(sonar3d.Error, match="truncated or corrupt"):
        sonar3d.import_holoocean(src, out)
    assert not os.path.exists(out)


# ---------------------------------------------------------------- navigation + frames

def test_read_navigation_ned(tmp_path):
    path = tmp_path / "nav.csv"
    path.write_text("time,x,y,z,roll,pitch,yaw\n0,1,2,3,0,0,90\n1,2,2,3,0,0,90\n")
    times, poses = sonar3d.read_navigation(
        str(path), config=sonar3d.NavCsvConfig(convention="ned", angles="deg"))
    np.testing.assert_allclose(times, [0, 1])
    np.testing.assert_allclose(poses[0][:3, 3], [2, 1, -3])  # east, north, up
    np.testing.assert_allclose(poses[0][:3, 0], [1, 0, 0], atol=1e-12)  # heading 90°: east
    # Keywords set the config's fields, as the importers' do.
    _, same = sonar3d.read_navigation(str(path), convention="ned")
    np.testing.assert_allclose(same, poses)
    path.write_text("time,x,y,z,roll,pitch,yaw\n0,1,2,3,0,0,1.5707963267948966\n")
    _, rad = sonar3d.read_navigation(str(path), convention="ned", angles="rad")
    np.testing.assert_allclose(rad[0], poses[0], atol=1e-12)
    with pytest.raises(sonar3d.Error, match="unknown setting 'degrees'"):
        sonar3d.read_navigation(str(path), degrees=True)
    # A TUM file needs no configuration.
    tum = tmp_path / "nav.tum"
    tum.write_text("0 1 2 3 0 0 0 1\n1 2 2 3 0 0 0 1\n")
    times, poses = sonar3d.read_navigation(str(tum))
    np.testing.assert_allclose(times, [0, 1])
    np.testing.assert_allclose(poses[1][:3, 3], [2, 2, 3])
    path.write_text("time,x,y,z,roll,pitch,yaw\n1,0,0,0,0,0,0\n0,0,0,0,0,0,0\n")
    with pytest.raises(sonar3d.Error, match="nav.csv:3"):
        sonar3d.read_navigation(str(path))


def test_import_frames(tmp_path, small_spec):
    small_spec.bit_depth = 8
    small_spec.intensity_scale = 1 / 255
    small_spec.T_vehicle_sonar = yaw_pose(0.0, [0.5, 0, 0])
    # Frames: written as a dataset's PNGs, then listed with their own clock.
    rng = np.random.default_rng(9)
    images = (rng.integers(0, 256, (3, 80, 48)) / 255).astype(np.float32)
    sonar3d.write_dataset(str(tmp_path / "src"), small_spec, images, poses=[np.eye(4)] * 3)
    (tmp_path / "times.csv").write_text(
        "timestamp,file\n" + "".join("%g,frames/%06d.png\n" % (1 + k, k) for k in range(3)))
    (tmp_path / "nav.csv").write_text("time,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n2.5,5,0,0,0,0,0\n")
    args = dict(images=str(tmp_path / "src"), times=str(tmp_path / "times.csv"),
                navigation=str(tmp_path / "nav.csv"), sonar=small_spec)
    with pytest.raises(sonar3d.Error, match="outside the navigation span"):
        sonar3d.import_frames(output=str(tmp_path / "ds"), **args)
    res = sonar3d.import_frames(output=str(tmp_path / "ds"), drop_outside=True, **args)
    assert res["frames"] == 2 and res["dropped"] == 1
    ds = sonar3d.read_dataset(str(tmp_path / "ds"))
    np.testing.assert_allclose(ds.pose(1)[:3, 3], [4.5, 0, 0], atol=1e-12)  # 2 m/s at t = 2
    np.testing.assert_allclose(ds.frame(1), images[1], atol=1e-6)


REAL_PINGS = os.path.join(os.path.dirname(__file__), "..", "..", "data", "oculus",
                          "three_pings_8bit.raw")


def test_import_oculus_real_pings(tmp_path):
    out = str(tmp_path / "ds")
    r = sonar3d.import_oculus(REAL_PINGS, out, static_sonar=True)
    assert r["pings"] == 3 and r["frames"] == 3 and r["version"] == 1
    assert not r["has_gains"] and r["dropped_bytes"] == 0
    assert "M1200d" in r["model"]
    ds = sonar3d.read_dataset(out)
    assert len(ds) == 3
    assert ds.spec.beams == 256 and ds.spec.range_bins == 703
    b = np.degrees(ds.spec.bearings)
    assert b[0] == pytest.approx(-30) and b[-1] == pytest.approx(30) and np.all(np.diff(b) > 0)
    raw = np.fromfile(REAL_PINGS, dtype=np.uint8)
    np.testing.assert_allclose(ds.frame(0), raw[2048:2048 + 703 * 256].reshape(703, 256) / 255.0,
                               atol=1e-7)
    # A cut stream keeps its whole pings; no navigation is an error.
    cut = tmp_path / "cut.raw"
    cut.write_bytes(raw[:-1000].tobytes())
    r = sonar3d.import_oculus(str(cut), str(tmp_path / "cut"), static_sonar=True)
    assert r["frames"] == 2 and r["dropped_bytes"] == 181016
    with pytest.raises(sonar3d.Error, match="--static"):
        sonar3d.import_oculus(REAL_PINGS, str(tmp_path / "x"))
