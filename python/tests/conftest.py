"""Shared fixtures of the sonar3d pytest suite (run by ctest: `make test`)."""
import json
import os
import pickle

import numpy as np
import pytest

import sonar3d


@pytest.fixture
def small_spec():
    spec = sonar3d.SonarSpec()
    spec.name = "small"
    spec.set_uniform_bearings(np.radians(30.0), 48)
    spec.r_min = 1.0
    spec.r_max = 3.0
    spec.range_bins = 80
    spec.vertical_aperture = np.radians(10.0)
    spec.beam_pattern = "flat"
    return spec


def write_holoocean(root, images, poses, range_bins, azimuth_bins, range_min, range_max,
                    azimuth_deg=60.0, elevation_deg=12.0, hz=10.0, numbers=None):
    """A HoloOcean recording as neusis/AONeuS ship it: Config.json and Data/NNN.pkl."""
    config = {
        "name": "HoveringImagingSonar", "world": "SimpleUnderwater", "main_agent": "auv0",
        "agents": [{
            "agent_name": "auv0", "agent_type": "HoveringAUV",
            "sensors": [
                {"sensor_type": "PoseSensor", "socket": "SonarSocket", "rotation": [0, 45, 0]},
                {"sensor_type": "ImagingSonar", "socket": "SonarSocket", "Hz": hz,
                 "rotation": [0, 45, 0],
                 "configuration": {"RangeBins": range_bins, "AzimuthBins": azimuth_bins,
                                   "RangeMin": range_min, "RangeMax": range_max,
                                   "Elevation": elevation_deg, "Azimuth": azimuth_deg,
                                   "AddSigma": 0.15, "MultSigma": 0.2}},
            ],
        }],
    }
    os.makedirs(os.path.join(root, "Data"), exist_ok=True)
    with open(os.path.join(root, "Config.json"), "w") as f:
        json.dump(config, f)
    numbers = numbers if numbers is not None else range(len(images))
    for n, img, pose in zip(numbers, images, poses):
        with open(os.path.join(root, "Data", "%03d.pkl" % n), "wb") as f:
            pickle.dump({"ImagingSonar": img, "PoseSensor": np.asarray(pose, np.float32)}, f)
    return root
