#!/usr/bin/env python3
"""Writes pairs of simulated surveys with a camera for colour change detection (`sonar3d diff
--colour-a/--colour-b`, docs/change.md "Colour change").

Sites:
  small   the small site of scripts/change_pair.py (riser, tank, pillar; its `changed` or `same`
          geometry) with colours: sand seabed, yellow riser, red tanks, grey pillar.
  field   the field of scripts/change_pair.py (54 x 38 m), coloured alike (pipelines grey).
  blocks  another site: 10 x 8 m terrain with rocks, five primitives (boxes, a cylinder, a
          sphere) of five colours, three lines at 3.5 m (A) and 4.2 m (B) altitude, no
          navigation drift between the frames but each survey its own seed.
GROWTH (yes|no): in B the tank (small) or the red box (blocks) has turned brown (marine growth).
Each survey's camera has its own lighting: A ambient 0.5, attenuation 0.05 / m; B ambient 0.25,
attenuation 0.1 / m (a weaker lamp, murkier water).

Usage: scripts/colour_change_pair.py {small|field|blocks} {changed|same} {yes|no} OUT_DIR
  writes OUT_DIR/change_a.yaml and OUT_DIR/change_b.yaml.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import change_pair  # noqa: E402

SAND, YELLOW, RED, GREY, BROWN = "[0.7, 0.6, 0.3]", "[0.8, 0.7, 0.1]", "[0.7, 0.08, 0.06]", \
    "[0.4, 0.4, 0.45]", "[0.35, 0.2, 0.08]"
LIGHT = {"a": (0.5, 0.05), "b": (0.25, 0.1)}


def camera(which):
    ambient, attenuation = LIGHT[which]
    return ("camera: {width: 320, height: 240, fx: 220, fy: 220, cx: 159.5, cy: 119.5, k1: -0.02, "
            "T_vehicle_camera: {translation: [0.1, 0, -0.2], rpy_deg: [180, 0, 0]}, rate_hz: 2, "
            "ambient: %g, attenuation_per_m: %g}\n" % (ambient, attenuation))


def small(which, kind, growth, site="small"):
    text = change_pair.scene(change_pair.SITES[site], which, kind)
    colours = {"seabed": SAND, "riser": YELLOW, "tank": RED, "tank_added": RED, "pillar": GREY,
               "pipeline_a": GREY, "pipeline_b": GREY}
    if growth and which == "b":
        colours["tank"] = BROWN
    out = []
    for line in text.splitlines():
        for name, c in colours.items():
            if line.startswith("  - {name: %s," % name):
                line = line[:-1] + ", color: %s}" % c
        out.append(line)
    return "\n".join(out) + "\n" + camera(which)


def blocks(which, kind, growth):
    z = 3.5 if which == "a" else 4.2
    red = BROWN if growth and which == "b" else RED
    objs = [
        ("seabed", "{type: terrain, size: [12, 10], cell: 0.05, relief: 0.2, wavelength: 5, "
         "trenches: 1, rocks: 12, seed: 8}", "[0, 0, 0]", 0, SAND),
        ("red_box", "{type: box, size: [1.0, 0.6, 0.5]}", "[1.5, 1.0, 0.2]", 25, red),
        ("yellow_box", "{type: box, size: [0.8, 0.8, 0.3]}", "[-2.0, -1.0, 0.12]", -10, YELLOW),
        ("grey_cylinder", "{type: cylinder, radius: 0.3, height: 0.8}", "[-1.5, 1.5, 0.35]", 0, GREY),
        ("green_box", "{type: box, size: [1.2, 0.4, 0.4]}", "[2.5, -1.5, 0.15]", 60,
         "[0.15, 0.5, 0.2]"),
        ("blue_sphere", "{type: sphere, radius: 0.3}", "[0.0, -2.0, 0.25]", 0, "[0.1, 0.2, 0.6]"),
    ]
    if kind == "changed" and which == "b":
        objs = [o for o in objs if o[0] != "grey_cylinder"]
    lines = ["# written by scripts/colour_change_pair.py: survey %s (blocks, %s)" % (which.upper(), kind),
             "seed: %d" % (21 if which == "a" else 22),
             "sensor: {preset: mb2250, r_min: 1.0, r_max: 6.5, range_bins: 250, "
             "T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}",
             "simulation: {elevation_step_deg: 0.1}",
             "objects:"]
    for name, prim, t, yaw, c in objs:
        lines.append("  - {name: %s, primitive: %s, pose: {translation: %s, rpy_deg: [0, 0, %g]}, "
                     "reflectivity: %s, color: %s}" % (name, prim, t, yaw,
                                                        "0.3" if name == "seabed" else "0.8", c))
    lines.append("trajectory: {type: lawnmower, x: [-4, 4], y: [-2.5, 2.5], z: %g, line_spacing: 2.5, "
                 "spacing: 0.04, period: 0.1}" % z)
    return "\n".join(lines) + "\n" + camera(which)


def main():
    if len(sys.argv) != 5 or sys.argv[1] not in ("small", "field", "blocks") or \
            sys.argv[2] not in ("changed", "same") or sys.argv[3] not in ("yes", "no"):
        sys.exit(__doc__)
    site, kind, growth, out = sys.argv[1], sys.argv[2], sys.argv[3] == "yes", sys.argv[4]
    os.makedirs(out, exist_ok=True)
    for which in ("a", "b"):
        with open("%s/change_%s.yaml" % (out, which), "w") as f:
            if site == "blocks":
                f.write(blocks(which, kind, growth))
            else:
                f.write(small(which, kind, growth, site))


if __name__ == "__main__":
    main()
