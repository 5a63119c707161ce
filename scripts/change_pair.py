#!/usr/bin/env python3
"""Writes pairs of simulated surveys of one site for change detection (`sonar3d diff`,
docs/change.md).

Survey A is the site as it was; survey B is the same site later, with:
  - the changes of `--kind changed`: the riser moved 30 cm and turned 10 degrees, the pillar
    removed, a second tank added (everything else untouched);
  - B's whole world frame offset from A's (as two surveys navigated from different fixes): the
    site seen in B's frame is A's site moved by T_b_a = Trans(shift) * Rz(yaw);
  - another seed (ray jitter, navigation bias walk) and other dead-reckoning errors.
`same` writes the same site twice (only the frame offset, seeds and drift differ); `drift` is
`changed` with ten times the navigation bias walk in B (a DVL bias wandering 10x faster).

Usage: scripts/change_pair.py {small|field} {changed|same|drift} OUT_DIR
  writes OUT_DIR/change_a.yaml, OUT_DIR/change_b.yaml and OUT_DIR/truth.json (T_a_b, changes).
"""
import json
import math
import sys

SITES = {
    # 10 x 8 m of seabed (relief, rocks), a downward-looking MB2250-like sonar 4 m up, four lines
    # 2 m apart: the unit-test pair (tests/test_change.cpp).
    "small": {
        "header": [
            "sensor: {preset: mb2250, r_min: 1.0, r_max: 6.0, range_bins: 250, "
            "T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}",
            "simulation: {elevation_step_deg: 0.1}",
        ],
        "seabed": "{type: terrain, size: [12, 10], cell: 0.05, relief: 0.15, wavelength: 6, "
                  "trenches: 0, rocks: 8, seed: 4}",
        "riser": (-2.0, 1.0, -0.05, 20.0),
        "tank": (2.2, -1.0, -0.05),
        "pillar": (1.8, 1.6, -0.05, 65.0),
        "tank_added": (-1.2, -1.6, -0.05),
        "pipelines": [],
        "trajectory": "{type: lawnmower, x: [-4, 4], y: [-3, 3], z: 4.0, line_spacing: 2.0, "
                      "spacing: 0.04, period: 0.1}",
        "nav_a": "{velocity_scale: 0.01, bias_walk: 0.00005, heading_bias_deg: 0.2, "
                 "depth_offset: 0.05}",
        "nav_b": "{velocity_scale: 0.01, bias_walk: 0.00005, heading_bias_deg: -0.1, "
                 "depth_offset: 0.09}",
        "seeds": (4, 11),
        "T_b_a": (0.25, -0.15, 0.04, 1.0),  # shift x, y, z (m), yaw (deg)
    },
    # The field of data/scenes/field.yaml (54 x 38 m, 8,679 frames).
    "field": {
        "header": [
            "sensor:",
            "  preset: mb2250",
            "  r_min: 3.0",
            "  r_max: 8.0",
            "  range_bins: 250",
            "  T_vehicle_sonar: {rpy_deg: [0, 90, 0]}",
            "simulation: {elevation_step_deg: 0.1}",
        ],
        "seabed": "{type: terrain, size: [54, 38], cell: 0.05, relief: 0.3, wavelength: 8, "
                  "trenches: 2, rocks: 40, seed: 6}",
        "riser": (-12.0, 6.0, -0.1, 20.0),
        "tank": (4.0, -8.0, -0.1),
        "pillar": (15.0, 7.0, -0.1, 65.0),
        "tank_added": (-4.0, 9.0, -0.1),
        "pipelines": [
            ("pipeline_a", (-11, 5, 0), (4.1, -8.1, 0)),
            ("pipeline_b", (4.6, -7, 0), (14.6, 6.75, 0)),
        ],
        "trajectory": "{type: lawnmower, x: [-25, 25], y: [-17, 17], z: 5.0, line_spacing: 6, "
                      "spacing: 0.04, turn_radius: 3, period: 0.1}",
        "nav_a": "{velocity_scale: 0.01, bias_walk: 0.00005, heading_bias_deg: 0.2, "
                 "depth_offset: 0.05}",
        "nav_b": "{velocity_scale: 0.01, bias_walk: 0.00005, heading_bias_deg: -0.1, "
                 "depth_offset: 0.09}",
        "seeds": (6, 13),
        "T_b_a": (0.35, -0.25, 0.05, 0.5),
    },
}

# The riser's change in B (in A's frame): moved 30 cm East, turned 10 degrees.
RISER_SHIFT = (0.3, 0.0)
RISER_TURN_DEG = 10.0


def transform(t_b_a, x, y, z, yaw_deg=0.0):
    """A point and yaw of A's world in B's world frame."""
    sx, sy, sz, a = t_b_a
    c, s = math.cos(math.radians(a)), math.sin(math.radians(a))
    return (c * x - s * y + sx, s * x + c * y + sy, z + sz, yaw_deg + a)


def pose(p):
    return "{translation: [%.4f, %.4f, %.4f], rpy_deg: [0, 0, %.4f]}" % p


def scene(site, which, kind):
    t = site["T_b_a"] if which == "b" else (0.0, 0.0, 0.0, 0.0)
    seed = site["seeds"][0 if which == "a" else 1]
    nav = site["nav_" + which]
    if which == "b" and kind == "drift":
        nav = nav.replace("bias_walk: 0.00005", "bias_walk: 0.0005")
    lines = ["# written by scripts/change_pair.py: survey %s of a change-detection pair (%s)"
             % (which.upper(), kind),
             "seed: %d" % seed,
             "navigation_error: " + nav]
    kind = "changed" if kind == "drift" else kind
    lines += site["header"]
    lines.append("objects:")
    lines.append("  - {name: seabed, primitive: %s, pose: %s, reflectivity: 0.3}"
                 % (site["seabed"], pose(transform(t, 0, 0, 0))))
    rx, ry, rz, ryaw = site["riser"]
    if which == "b" and kind == "changed":
        rx, ry, ryaw = rx + RISER_SHIFT[0], ry + RISER_SHIFT[1], ryaw + RISER_TURN_DEG
    objs = [("riser", "riser", (rx, ry, rz, ryaw)), ("tank", "tank", site["tank"] + (0.0,))]
    if which == "a" or kind == "same":
        objs.append(("pillar", "pillar", site["pillar"]))
    if which == "b" and kind == "changed":
        objs.append(("tank_added", "tank", site["tank_added"] + (0.0,)))
    for name, ref, (x, y, z, yaw) in objs:
        lines.append("  - {name: %s, reference: %s, pose: %s, reflectivity: 0.8}"
                     % (name, ref, pose(transform(t, x, y, z, yaw))))
    for name, a, b in site["pipelines"]:
        pa, pb = transform(t, *a), transform(t, *b)
        lines.append("  - {name: %s, pipeline: {from: [%.4f, %.4f, %.4f], to: [%.4f, %.4f, %.4f], "
                     "radius: 0.2, burial: 0.5}, reflectivity: 0.7}" % (name, *pa[:3], *pb[:3]))
    lines.append("trajectory: " + site["trajectory"])
    return "\n".join(lines) + "\n"


def main():
    if len(sys.argv) != 4 or sys.argv[1] not in SITES or sys.argv[2] not in ("changed", "same", "drift"):
        sys.exit(__doc__)
    site, kind, out = SITES[sys.argv[1]], sys.argv[2], sys.argv[3]
    for which in ("a", "b"):
        with open("%s/change_%s.yaml" % (out, which), "w") as f:
            f.write(scene(site, which, kind))
    # T_a_b = inverse(T_b_a): maps B's world into A's.
    sx, sy, sz, a = site["T_b_a"]
    c, s = math.cos(math.radians(a)), math.sin(math.radians(a))
    R = [[c, s, 0], [-s, c, 0], [0, 0, 1]]  # R_b_a transposed
    tt = [-(R[i][0] * sx + R[i][1] * sy + R[i][2] * sz) for i in range(3)]
    T_a_b = [R[0] + [tt[0]], R[1] + [tt[1]], R[2] + [tt[2]], [0, 0, 0, 1]]
    truth = {"T_a_b": [v for row in T_a_b for v in row],
             "changes": {"riser": "moved 0.3 m, turned 10 deg", "pillar": "removed",
                         "tank": "added"} if kind != "same" else {}}
    with open(out + "/truth.json", "w") as f:
        json.dump(truth, f, indent=1)


if __name__ == "__main__":
    main()
