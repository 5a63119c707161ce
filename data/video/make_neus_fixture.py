#!/usr/bin/python3
"""IDR/NeuS camera fixtures for tests/test_video.cpp and seeds for fuzz/fuzz_npz.cpp.

Three cameras on a circle of radius 2 m at height 1 m, looking at the origin (OpenCV axes:
+z forward, +y down, world z up), K = [[500, 0, 319.5], [0, 510, 239.5], [0, 0, 1]].
world_mat_i = lambda_i * K [R | -R C] with lambda = 1, 2.5, -1.7 (a projection matrix is defined
up to scale); scale_mat_i = [[1.5 I, (0.2, -0.1, 0.5)], [0 0 0 1]].
Run with Debian's python3 (numpy): /usr/bin/python3 data/video/make_neus_fixture.py
"""
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CORPUS = os.path.join(HERE, "..", "..", "fuzz", "corpus", "npz")

K = np.array([[500.0, 0, 319.5], [0, 510.0, 239.5], [0, 0, 1]])
SCALES = [1.0, 2.5, -1.7]
S = np.eye(4)
S[:3, :3] *= 1.5
S[:3, 3] = [0.2, -0.1, 0.5]


def look_at(eye, target):
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)  # columns: camera axes in the world (R_world_camera)


def cameras():
    out = {}
    for i, lam in enumerate(SCALES):
        a = 2 * np.pi * i / 3
        C = np.array([2 * np.cos(a), 2 * np.sin(a), 1.0])
        R_wc = look_at(C, np.zeros(3))
        R = R_wc.T  # world -> camera
        P = np.eye(4)
        P[:3, :4] = lam * K @ np.hstack([R, (-R @ C)[:, None]])
        if i == 1:
            P[3] = [0, 0, 0, 1]
        out[f"world_mat_{i}"] = P
        out[f"scale_mat_{i}"] = S
        out[f"world_mat_inv_{i}"] = np.linalg.inv(P) if i == 1 else np.eye(4)
    return out


def main():
    os.makedirs(CORPUS, exist_ok=True)
    cams = cameras()
    np.savez(os.path.join(HERE, "cameras_neus.npz"), **cams)
    # float32 3x4 world_mats, deflated: the other layout IDR-style files come in.
    cams32 = {k: (v[:3].astype(np.float32) if k.startswith("world_mat_") and "inv" not in k else v)
              for k, v in cams.items()}
    np.savez_compressed(os.path.join(HERE, "cameras_neus_compressed.npz"), **cams32)
    np.savez(os.path.join(CORPUS, "stored.npz"), **cams)
    np.savez_compressed(os.path.join(CORPUS, "deflated.npz"), **cams32)
    np.savez_compressed(os.path.join(CORPUS, "one_array.npz"), world_mat_0=cams["world_mat_0"])
    np.save(os.path.join(CORPUS, "matrix.npy"), cams["scale_mat_0"])


if __name__ == "__main__":
    main()
