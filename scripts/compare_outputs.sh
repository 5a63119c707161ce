#!/usr/bin/env bash
# Behaviour unchanged, and proven (issue 24, item 4): run the README's tour with one build, run it
# again with another, and compare every file the two runs wrote, byte for byte.
#
#   scripts/compare_outputs.sh run BUILD_DIR OUT_DIR   run the tour with BUILD_DIR/bin/sonar3d,
#                                                      its outputs into OUT_DIR (must not exist)
#   scripts/compare_outputs.sh diff OUT_A OUT_B        compare two runs' outputs; exit 1 if any
#                                                      file differs or is only in one of them
#
# A refactoring is checked by running the tour with the build before it and the build after it
# (e.g. two worktrees), then `diff`. What may legitimately change from run to run is left out of
# the comparison and named: in JSON files, keys that hold wall-clock times, memory peaks, thread
# counts or dates (see VOLATILE below); in text files, lines of timing. Everything else — clouds,
# images, GeoTIFFs, meshes, trajectories, reports' figures — must be identical to the byte.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
src="$(cd "$here/.." && pwd)"

usage() { sed -n '4,8p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[ $# -eq 3 ] || usage

case "$1" in
run)
  build="$(cd "$2" && pwd)"
  out="$3"
  [ -x "$build/bin/sonar3d" ] || { echo "compare_outputs: no $build/bin/sonar3d"; exit 2; }
  [ ! -e "$out" ] || { echo "compare_outputs: $out exists; give a new directory"; exit 2; }
  mkdir -p "$out"
  out="$(cd "$out" && pwd)"
  # The tour as readme_tour.sh runs it: a scratch directory that sees data/, scripts/ and bin/.
  ln -s "$src/data" "$out/data"; ln -s "$src/scripts" "$out/scripts"
  mkdir -p "$out/build"; ln -s "$build/bin" "$out/build/bin"
  awk '/^## A one-minute tour/{t=1} t&&/^```sh/{b=1;next} b&&/^```/{exit} b' "$src/README.md" \
    > "$out/tour.sh"
  [ -s "$out/tour.sh" ] || { echo "compare_outputs: README tour block not found"; exit 1; }
  echo "compare_outputs: running the README tour with $build/bin/sonar3d into $out"
  # One thread, so that parallel reductions cannot reorder floating-point sums between runs.
  (cd "$out" && OMP_NUM_THREADS=1 bash -euo pipefail tour.sh > "$out/tour.log" 2>&1) || {
    echo "compare_outputs: the tour failed; see $out/tour.log"; exit 1; }
  echo "compare_outputs: $(find "$out/tour" -type f | wc -l) files written"
  ;;
diff)
  a="$2"; b="$3"
  [ -d "$a/tour" ] && [ -d "$b/tour" ] || { echo "compare_outputs: $a/tour or $b/tour missing (run 'run' first)"; exit 2; }
  /usr/bin/python3 - "$a/tour" "$b/tour" <<'PY'
import csv, io, json, os, re, sys

a_root, b_root = sys.argv[1], sys.argv[2]
# Keys whose values are measurements of the run, not results: durations, memory, threads, dates,
# and the paths of the scratch directory the run used. Timestamps of the data (`time_s`,
# `t_mid_s`, `time_reference_s`), rates (`rate_m_per_s`) and settings (`period_s`) are results:
# a key ending in `_s` is a duration only when it names a step of the run (DURATION_S).
DURATION_S = {"runtime_s", "simulate_s", "reconstruct_s"}
VOLATILE_WORDS = re.compile(
    r"(^|_)(seconds|ms|timing|timings|elapsed|wall|cpu|peak|rss|memory|mb|gb|"
    r"threads|date|created|generated|version|host)(_|$)|_ms$|per_frame|duration",
    re.I)

class _Volatile:
    def search(self, key):
        return key in DURATION_S or VOLATILE_WORDS.search(key)

VOLATILE = _Volatile()

def files(root):
    out = set()
    for d, _, names in os.walk(root):
        for n in names:
            out.add(os.path.relpath(os.path.join(d, n), root))
    return out

def strip(v, dropped, root):
    """A JSON value without the run's measurements, its own directory written as <run>."""
    if isinstance(v, dict):
        kept = {}
        for k, x in v.items():
            if VOLATILE.search(k):
                dropped.add(k)
            else:
                kept[k] = strip(x, dropped, root)
        return kept
    if isinstance(v, list):
        return [strip(x, dropped, root) for x in v]
    if isinstance(v, str):
        return v.replace(os.path.dirname(root), "<run>")
    return v

def csv_rows(data, dropped):
    rows = list(csv.reader(io.StringIO(data.decode("utf-8", "replace"))))
    if not rows:
        return rows
    keep = [i for i, h in enumerate(rows[0]) if not VOLATILE.search(h)]
    dropped.update(h for h in rows[0] if VOLATILE.search(h))
    return [[r[i] for i in keep if i < len(r)] for r in rows]

# The reports carry their data as one JSON document in a script element.
DATA = re.compile(rb'(<script type="application/json" id="sonar3d-data">)(.*?)(</script>)', re.S)

def html_parts(data, dropped, root):
    docs = [strip(json.loads(m.group(2)), dropped, root) for m in DATA.finditer(data)]
    return DATA.sub(rb"\1\3", data), docs

def text_lines(data):
    # Lines that report timing ("carving 1.2 s", "12 ms/frame", "took 3 s") are measurements.
    timing = re.compile(r"\b\d+(\.\d+)?\s*(s|ms|min|MB|GB|ms/frame)\b|seconds|elapsed", re.I)
    return [l for l in data.decode("utf-8", "replace").splitlines() if not timing.search(l)]

fa, fb = files(a_root), files(b_root)
only_a, only_b = sorted(fa - fb), sorted(fb - fa)
same = differ = 0
dropped = set()
for rel in sorted(fa & fb):
    pa, pb = os.path.join(a_root, rel), os.path.join(b_root, rel)
    da, db = open(pa, "rb").read(), open(pb, "rb").read()
    if da == db:
        same += 1
        continue
    equal = False
    if rel.endswith(".json"):
        try:
            equal = strip(json.loads(da), dropped, a_root) == strip(json.loads(db), dropped, b_root)
        except ValueError:
            equal = False
    elif rel.endswith(".csv"):
        equal = csv_rows(da, dropped) == csv_rows(db, dropped)
    elif rel.endswith(".html"):
        try:
            equal = html_parts(da, dropped, a_root) == html_parts(db, dropped, b_root)
        except ValueError:
            equal = False
    elif rel.endswith((".txt", ".log", ".md")) and b"\0" not in da:
        equal = text_lines(da) == text_lines(db)
    if equal:
        same += 1
    else:
        differ += 1
        print(f"DIFFERS  {rel} ({len(da)} vs {len(db)} bytes)")
for rel in only_a:
    print(f"ONLY IN A  {rel}")
for rel in only_b:
    print(f"ONLY IN B  {rel}")
print(f"compare_outputs: {same} files the same, {differ} differ, {len(only_a)} only in A, "
      f"{len(only_b)} only in B")
if dropped:
    print("  (measurements of the run left out of JSON comparisons: " +
          ", ".join(sorted(dropped)) + ")")
sys.exit(1 if differ or only_a or only_b else 0)
PY
  ;;
*) usage ;;
esac
