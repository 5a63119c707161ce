#!/usr/bin/env python3
"""Writes a small HoloOcean imaging-sonar recording, shaped like those of neusis/AONeuS, so that
`sonar3d import holoocean` can be tried without a HoloOcean install:

    python3 scripts/holoocean_example.py RECORDING [--frames N]

RECORDING/Config.json describes a 60 deg x 12 deg sonar (64 azimuth bins, 100 range bins from
0.5 to 4.5 m, 10 Hz) on a HoveringAUV; RECORDING/Data/NNN.pkl each hold {"ImagingSonar": float32
range x azimuth image, "PoseSensor": float32 4x4 pose}. The vehicle rises 2 cm a frame in front of
a flat wall 3 m away, so every image shows one bright arc. Needs python3 with numpy. Refuses to
write into an existing, non-empty directory."""
import argparse
import json
import os
import pickle
import sys

import numpy as np

RANGE_BINS, AZIMUTH_BINS = 100, 64
RANGE_MIN, RANGE_MAX = 0.5, 4.5
AZIMUTH_DEG, ELEVATION_DEG = 60.0, 12.0


def config():
    sonar = {"RangeBins": RANGE_BINS, "AzimuthBins": AZIMUTH_BINS, "RangeMin": RANGE_MIN,
             "RangeMax": RANGE_MAX, "InitOctreeRange": 50, "Elevation": ELEVATION_DEG,
             "Azimuth": AZIMUTH_DEG, "AzimuthStreaks": -1, "ScaleNoise": True, "AddSigma": 0.15,
             "MultSigma": 0.2, "RangeSigma": 0.0, "MultiPath": True, "ViewOctree": -1}
    return {"name": "HoveringImagingSonar", "world": "SimpleUnderwater", "main_agent": "auv0",
            "ticks_per_sec": 200, "frames_per_sec": True, "octree_min": 0.02, "octree_max": 5.0,
            "agents": [{"agent_name": "auv0", "agent_type": "HoveringAUV", "sensors": [
                {"sensor_type": "PoseSensor", "socket": "SonarSocket"},
                {"sensor_type": "ImagingSonar", "socket": "SonarSocket", "Hz": 10,
                 "configuration": sonar}],
                "control_scheme": 0, "location": [0, 0, -5], "rotation": [0, 0, 0]}]}


def frame(k, rng):
    # A wall at x = 3 m seen head-on: the return of bearing b arrives at r = 3 / cos(b).
    bearings = np.radians(np.linspace(-AZIMUTH_DEG / 2, AZIMUTH_DEG / 2, AZIMUTH_BINS))
    ranges = RANGE_MIN + (np.arange(RANGE_BINS) + 0.5) * (RANGE_MAX - RANGE_MIN) / RANGE_BINS
    wall = 3.0 / np.cos(bearings)
    img = np.exp(-((ranges[:, None] - wall[None, :]) / 0.03) ** 2)
    img = np.clip(img + 0.02 * rng.random(img.shape), 0, 1).astype(np.float32)
    pose = np.eye(4, dtype=np.float32)
    pose[2, 3] = -5.0 + 0.02 * k
    return {"ImagingSonar": img, "PoseSensor": pose}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recording", help="directory to create")
    ap.add_argument("--frames", type=int, default=20, help="number of frames (1-1000)")
    a = ap.parse_args()
    if not 1 <= a.frames <= 1000:
        sys.exit(f"holoocean_example.py: error: --frames {a.frames}: must be within 1-1000")
    if os.path.isdir(a.recording) and os.listdir(a.recording):
        sys.exit(f"holoocean_example.py: error: '{a.recording}' exists and is not empty")
    os.makedirs(os.path.join(a.recording, "Data"), exist_ok=True)
    with open(os.path.join(a.recording, "Config.json"), "w") as f:
        json.dump(config(), f, indent=1)
    rng = np.random.default_rng(1)
    for k in range(a.frames):
        with open(os.path.join(a.recording, "Data", f"{k:03d}.pkl"), "wb") as f:
            pickle.dump(frame(k, rng), f)
    print(f"wrote {a.frames} frames to {a.recording}")


if __name__ == "__main__":
    main()
