#!/usr/bin/env python3
"""Ghost removal by default on open structures never tuned for (issue 29, docs/carving.md).

For each structure of data/scenes/ghost_*.yaml, each vertical aperture (10, 20, 30 degrees) and
each trajectory -- the scene's two vertical passes ending 0.5 m over the top ("short"), the same
passes ending 2 * 3.7 m * tan(A_v / 2) + 0.1 m over it ("long", the rule of docs/experiments.md
for the structure's far side), and 9 level orbits of 24 frames at 3 m ("orbit") -- it simulates
the dataset, carves it with the defaults and with each option switched, scores the cloud against
the truth (sonar3d evaluate) and writes one CSV row per run and a Markdown table.

Usage: bench/ghost_defaults.py [--build build | --sonar3d BIN] [--work /tmp/sonar3d_ghosts]
           [--voxel 0.02] [--apertures 10,20,30] [--trajectories short,long,orbit]
           [--runs default,none,flags] [--structures braced_frame,manifold,...] [--threads 2]
           [--simulate-only]
The CSV (WORK/ghost_defaults.csv) and the table (WORK/ghost_defaults.md) are rewritten each run;
datasets simulated from the same scene text are reused. The whole default table is 135
reconstructions at 2 cm (about 20 min for the 45 of one aperture on 2 cores at load average
~10). bench/ghost_defaults.csv holds the runs of docs/carving.md ("Ghost removal by default").
"""
import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The option sets: the defaults, then each ghost filter switched off, then today's flags.
RUNS = {
    "default": [],
    "none": ["--no-explain-returns", "--no-auto-min-bracket"],  # the defaults before issue 29
    "bracket-only": ["--no-explain-returns"],
    "explain-only": ["--no-auto-min-bracket"],
    "flags": ["--min-bracket", "0.5"],  # min_bracket 0.5 always, explanation on
}


def structure_top(scene):
    """Highest point of the scene's objects (boxes and cylinders, as the ghost scenes use)."""
    top = -1e9
    for o in scene["objects"]:
        p = o.get("primitive", {})
        t = o.get("pose", {}).get("translation", [0, 0, 0])
        rpy = [math.radians(a) for a in o.get("pose", {}).get("rpy_deg", [0, 0, 0])]
        if p.get("type") == "box":
            # Half extent along z of a box rotated by roll/pitch (yaw keeps z).
            sx, sy, sz = [0.5 * v for v in p["size"]]
            r, pch = rpy[0], rpy[1]
            ext = (abs(-math.sin(pch)) * sx + abs(math.sin(r) * math.cos(pch)) * sy +
                   abs(math.cos(r) * math.cos(pch)) * sz)
            top = max(top, t[2] + ext)
        elif p.get("type") == "cylinder":
            # Base at the pose, axis along the rotated z; radius across it.
            r, pch = rpy[0], rpy[1]
            axis_z = math.cos(r) * math.cos(pch)
            h, rad = p["height"], p["radius"]
            across = rad * math.sqrt(max(0.0, 1 - axis_z * axis_z))
            top = max(top, t[2] + max(0.0, axis_z * h) + across)
    return top


def variant(base, aperture, trajectory):
    scene = yaml.safe_load(open(base))
    scene["sensor"]["preset"] = "sim-%ddeg" % aperture
    top = structure_top(scene)
    segs = scene["trajectory"]["segments"]
    if trajectory == "long":
        end = top + 2 * 3.7 * math.tan(math.radians(aperture) / 2) + 0.1
        for s in segs:
            s["end"][2] = round(end, 3)
    elif trajectory == "orbit":
        z0 = segs[0]["start"][2]
        levels = [z0 + (top + 0.2 - z0) * k / 8 for k in range(9)]
        scene["trajectory"]["segments"] = [
            {"type": "orbit", "center": [0, 0, round(z, 3)], "radius": 3.0, "count": 24,
             "start_deg": 180.0 + (7.5 if k % 2 else 0.0)} for k, z in enumerate(levels)]
    return scene


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--sonar3d", default="", help="the binary (default: BUILD/bin/sonar3d)")
    ap.add_argument("--work", default="/tmp/sonar3d_ghosts")
    ap.add_argument("--voxel", default="0.02")
    ap.add_argument("--apertures", default="10,20,30")
    ap.add_argument("--trajectories", default="short,long,orbit")
    # bracket-only and explain-only switch one filter off each (--runs ...,bracket-only,...).
    ap.add_argument("--runs", default="default,none,flags")
    ap.add_argument("--structures", default="")
    ap.add_argument("--threads", default="2")
    ap.add_argument("--simulate-only", action="store_true", help="only write the datasets")
    a = ap.parse_args()
    s3d = a.sonar3d or os.path.join(a.build, "bin", "sonar3d")
    os.makedirs(a.work, exist_ok=True)
    bases = sorted(f for f in os.listdir(os.path.join(ROOT, "data", "scenes"))
                   if f.startswith("ghost_") and f.endswith(".yaml"))
    if a.structures:
        want = a.structures.split(",")
        bases = [b for b in bases if b[len("ghost_"):-len(".yaml")] in want]
    rows = []
    csv_path = os.path.join(a.work, "ghost_defaults.csv")
    fields = ["structure", "aperture", "trajectory", "run", "frames", "median_cm", "coverage",
              "outliers", "points", "integrate_ms", "occlusion_ms", "peak_mb", "auto_bracket",
              "ghosts_explained"]
    for base in bases:
        name = base[len("ghost_"):-len(".yaml")]
        for aperture in [int(x) for x in a.apertures.split(",")]:
            for traj in a.trajectories.split(","):
                tag = "%s_%d_%s" % (name, aperture, traj)
                scene_path = os.path.join(a.work, tag + ".yaml")
                ds = os.path.join(a.work, tag)
                with open(scene_path, "w") as f:
                    yaml.safe_dump(variant(os.path.join(ROOT, "data", "scenes", base), aperture,
                                           traj), f, sort_keys=False)
                # A dataset written from the same scene text is reused.
                if not (os.path.isdir(ds) and os.path.exists(ds + ".scene") and
                        open(ds + ".scene").read() == open(scene_path).read()):
                    run([s3d, "-q", "simulate", scene_path, "-o", ds, "--overwrite"])
                    with open(ds + ".scene", "w") as f:
                        f.write(open(scene_path).read())
                if a.simulate_only:
                    continue
                for rname in a.runs.split(","):
                    out = os.path.join(a.work, "%s_%s" % (tag, rname))
                    cmd = ["/usr/bin/time", "-v", s3d, "-q", "reconstruct", ds, "--method", "carve",
                           "--voxel-size", a.voxel, "--threads", a.threads,
                           "--roi", "-2", "-2", "-0.03", "2", "2", "3.5", "-o", out + ".ply",
                           "--json", out + ".json", "--overwrite", "--allow-empty"] + RUNS[rname]
                    p = run(cmd)
                    peak = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)",
                                         p.stderr).group(1)) / 1e3
                    rep = json.load(open(out + ".json"))
                    ev = out + "_eval.json"
                    run([s3d, "-q", "evaluate", out + ".ply", "-t", ds, "--json", ev,
                         "--overwrite"])
                    m = [x for x in json.load(open(ev)) if x["object"] == "all"][0]
                    carve = rep.get("carve", rep)
                    br = rep.get("bracketing", {})
                    row = {
                        "structure": name, "aperture": aperture, "trajectory": traj,
                        "run": rname, "frames": carve.get("frames"),
                        "median_cm": 100 * (m["median_error_m"] or 0),
                        "coverage": 100 * (m["coverage"] or 0),
                        "outliers": 100 * (m["outliers"] or 0), "points": m["num_points"],
                        "integrate_ms": carve.get("integrate_ms_per_frame"),
                        "occlusion_ms": carve.get("occlusion_ms_per_frame"), "peak_mb": peak,
                        "auto_bracket": br.get("min_bracket_auto"),
                        "ghosts_explained": carve.get("ghosts_explained", 0)}
                    rows.append(row)
                    print("%-28s %-12s %6.2f cm %5.1f %% cov %5.1f %% out  occl %6.1f ms/frame"
                          "  %4.0f MB" % (tag, rname, row["median_cm"], row["coverage"],
                                          row["outliers"], row["occlusion_ms"] or 0, peak),
                          flush=True)
                    with open(csv_path, "w", newline="") as f:
                        w = csv.DictWriter(f, fieldnames=fields)
                        w.writeheader()
                        w.writerows(rows)
    # The table: one line per dataset, median / coverage / outliers per run.
    runs = a.runs.split(",")
    md = ["| structure | A_v | trajectory | " + " | ".join(runs) + " |",
          "|---|---|---|" + "---|" * len(runs)]
    keys = []
    for r in rows:
        k = (r["structure"], r["aperture"], r["trajectory"])
        if k not in keys:
            keys.append(k)
    for k in keys:
        cells = []
        for rn in runs:
            r = [x for x in rows if (x["structure"], x["aperture"], x["trajectory"]) == k and
                 x["run"] == rn]
            cells.append("%.2f / %.1f / %.1f" % (r[0]["median_cm"], r[0]["coverage"],
                                                  r[0]["outliers"]) if r else "")
        md.append("| %s | %d° | %s | %s |" % (k[0], k[1], k[2], " | ".join(cells)))
    with open(os.path.join(a.work, "ghost_defaults.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    sys.exit(main())
