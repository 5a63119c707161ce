"""The ARIS and ROS bag importers through the bindings (issue 24 item 1, issue 27 item 4): their
configuration classes come from the same declaration as the command line's flags, and the same
settings write the same dataset from Python as from `sonar3d import`."""
import os
import struct
import subprocess

import numpy as np
import pytest

import sonar3d

CLI = os.environ.get("SONAR3D_CLI")
needs_cli = pytest.mark.skipif(not CLI, reason="SONAR3D_CLI (the sonar3d binary) is set by ctest")

FILES = ["sonar.yaml", "frames.csv", "navigation.tum"]


def cli(*args):
    r = subprocess.run([CLI, "-q", *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r.stdout


def same_dataset(a, b):
    for f in FILES + sorted("frames/" + n for n in os.listdir(os.path.join(a, "frames"))):
        with open(os.path.join(a, f), "rb") as fa, open(os.path.join(b, f), "rb") as fb:
            assert fa.read() == fb.read(), f


def write_aris(path, n=4, beams=48, samples=40, header_nav=True):
    """An ARIS file in Sound Metrics' published layout (as sonar3d's write_aris): a 1024-byte
    file header, then per frame a 1024-byte frame header and samples x beams bytes."""
    fh = bytearray(1024)
    struct.pack_into("<I", fh, 0, 0x05464444)      # Version: "DDF" 0x05
    struct.pack_into("<I", fh, 4, n)               # FrameCount
    struct.pack_into("<I", fh, 16, beams)          # NumRawBeams
    struct.pack_into("<I", fh, 24, samples)        # SamplesPerChannel
    out = bytes(fh)
    rng = np.random.default_rng(3)
    for k in range(n):
        h = bytearray(1024)
        struct.pack_into("<I", h, 0, k)                          # FrameIndex
        struct.pack_into("<Q", h, 4, 1_000_000 + 100_000 * k)    # FrameTime, us
        struct.pack_into("<I", h, 12, 0x05464444)                # Version
        struct.pack_into("<Q", h, 20, 1_005_000 + 100_000 * k)   # sonarTimeStamp, us
        if header_nav:
            struct.pack_into("<f", h, 128, 2.0 + 0.1 * k)        # Depth, m
            struct.pack_into("<f", h, 152, 10.0 * k)             # Heading, deg
            struct.pack_into("<d", h, 172, 47.6 + 2e-6 * k)      # Latitude
            struct.pack_into("<d", h, 180, -122.3)               # Longitude
        struct.pack_into("<I", h, 436, 1)                        # PingMode: 48 beams
        struct.pack_into("<I", h, 452, 20)                       # SamplePeriod, us
        struct.pack_into("<f", h, 464, 1500.0)                   # SoundSpeed, m/s
        struct.pack_into("<I", h, 468, samples)                  # SamplesPerBeam
        struct.pack_into("<I", h, 476, 1600)                     # SampleStartDelay, us
        struct.pack_into("<I", h, 516, 1)                        # ReorderedSamples
        out += bytes(h) + rng.integers(0, 256, samples * beams, dtype=np.uint8).tobytes()
    with open(path, "wb") as f:
        f.write(out)
    return str(path)


def test_import_configs_are_declared_classes():
    cfg = sonar3d.ArisImportConfig(clock="sonar", mount=[0.4, 0, -0.2, 0, 20, 0])
    assert cfg.clock == "sonar" and cfg.mount == [0.4, 0, -0.2, 0, 20, 0]
    assert cfg.vertical_aperture_deg is None and cfg.navigation_csv.angles == "deg"
    assert "deg" in sonar3d.ArisImportConfig.vertical_aperture_deg.__doc__
    assert "--mount" in sonar3d.ArisImportConfig.mount.__doc__
    assert "m, deg" in sonar3d.RosbagImportConfig.mount.__doc__
    d = sonar3d.OculusImportConfig(static_sonar=True, gains="divide").to_dict()
    assert d["gains"] == "divide" and d["navigation_csv"] == {"convention": "enu", "angles": "deg"}
    assert sonar3d.HoloOceanImportConfig().bins == "sample"
    assert sonar3d.FrameImportConfig(time_offset=2.5).time_offset == 2.5
    with pytest.raises(sonar3d.Error, match="vertical_aperture_deg must lie in"):
        sonar3d.ArisImportConfig(vertical_aperture_deg=200)
    with pytest.raises(sonar3d.Error, match="must be one of pc or sonar"):
        sonar3d.ArisImportConfig(clock="gps")
    with pytest.raises(sonar3d.Error, match="angles must be one of deg or rad"):
        sonar3d.NavCsvConfig(angles="grad")


def test_import_aris_bad_settings(tmp_path):
    f = write_aris(tmp_path / "f.aris")
    with pytest.raises(sonar3d.Error, match="unknown setting 'mounting'.*mount"):
        sonar3d.import_aris(f, str(tmp_path / "a"), mounting=[0] * 6)
    with pytest.raises(sonar3d.Error, match="mount must hold 6 numbers"):
        sonar3d.import_aris(f, str(tmp_path / "a"), mount=[1, 2, 3])
    with pytest.raises(sonar3d.Error, match="nav_source 'file' needs a navigation file"):
        sonar3d.import_aris(f, str(tmp_path / "a"), nav_source="file")
    assert not os.path.exists(tmp_path / "a")


@needs_cli
def test_import_aris_matches_the_cli(tmp_path):
    f = write_aris(tmp_path / "dive.aris")
    cli("import", "aris", f, "-o", tmp_path / "cli", "--clock", "sonar",
        "--mount", "0.4,0,-0.2,0,20,0", "--vertical-aperture-deg", "12")
    seen = []
    r = sonar3d.import_aris(f, str(tmp_path / "py"),
                            config=sonar3d.ArisImportConfig(clock="sonar"),
                            mount=[0.4, 0, -0.2, 0, 20, 0], vertical_aperture_deg=12,
                            progress=lambda done, total: seen.append((done, total)))
    same_dataset(str(tmp_path / "cli"), str(tmp_path / "py"))
    assert r["frames"] == 4 and r["beams"] == 48 and r["samples"] == 40
    assert r["nav_source"] == "header" and r["dropped"] == 0
    assert r["settings"]["clock"] == "sonar" and r["settings"]["vertical_aperture_deg"] == 12
    assert np.degrees(r["spec"].vertical_aperture) == pytest.approx(12)
    assert seen and seen[-1][0] == seen[-1][1]
    # The CLI's printed configuration is the Python one.
    printed = cli("import", "aris", "--clock", "sonar", "--mount", "0.4,0,-0.2,0,20,0",
                  "--vertical-aperture-deg", "12", "--print-config")
    assert "mount: [0.4, 0, -0.2, 0, 20, 0]" in printed and "vertical_aperture_deg: 12" in printed
    ds = sonar3d.read_dataset(str(tmp_path / "py"))
    assert len(ds) == 4


@needs_cli
@pytest.mark.parametrize("ros1", [True, False])
def test_import_rosbag_matches_the_cli(tmp_path, small_spec, ros1):
    small_spec.bit_depth = 8
    small_spec.intensity_scale = 1 / 255
    rng = np.random.default_rng(5)
    images = (rng.integers(0, 256, (3, 80, 48)) / 255).astype(np.float32)
    poses = np.stack([np.eye(4)] * 3)
    poses[:, :3, 3] = [[0.1 * k, 0.0, -1.0] for k in range(3)]
    sonar3d.write_dataset(str(tmp_path / "src"), small_spec, images, poses=poses)
    bag = tmp_path / ("run.bag" if ros1 else "run")
    cli("export", "rosbag", tmp_path / "src", "-o", bag, *(["--ros1"] if ros1 else []))
    cli("import", "rosbag", bag, "-o", tmp_path / "cli", "--vertical-aperture-deg", "10")
    r = sonar3d.import_rosbag(str(bag), str(tmp_path / "py"), vertical_aperture_deg=10)
    same_dataset(str(tmp_path / "cli"), str(tmp_path / "py"))
    assert r["frames"] == 3 and r["navigation_samples"] >= 3 and r["dropped"] == 0
    assert r["sonar_type"].endswith("ProjectedSonarImage")
    assert r["format"].startswith("ROS 1" if ros1 else "ROS 2")
    assert r["settings"]["sonar_topic"] and r["settings"]["nav_topic"]  # found by type
    assert len(r["topics"]) == 2
    # A fixed sonar with a mounting: the same again, from a config object.
    cfg = sonar3d.RosbagImportConfig(static_sonar=True, mount=[0, 0, 0.5, 0, 30, 0])
    cli("import", "rosbag", bag, "-o", tmp_path / "cli2", "--static", "--mount", "0,0,0.5,0,30,0")
    r2 = sonar3d.import_rosbag(str(bag), str(tmp_path / "py2"), config=cfg)
    same_dataset(str(tmp_path / "cli2"), str(tmp_path / "py2"))
    assert r2["mounting_source"] == "--mount" and r2["navigation_samples"] == 0
