#!/bin/bash
# Runs each fuzz target for SECONDS seconds, one at a time at low priority, and prints one line
# per target: name, seconds, executions, result. Used for the table in docs/fuzzing.md.
# Usage: fuzz/run_campaign.sh BUILD_DIR SECONDS [targets...]
build=$1; secs=$2; shift 2
targets=${*:-dataset scene sweep ply mesh holoocean_config pickle navcsv aris rosmsg rosbag}
root=$(cd "$(dirname "$0")/.." && pwd)
for t in $targets; do
  mkdir -p "$build/corpus/$t" && cp -n "$root/fuzz/corpus/$t/"* "$build/corpus/$t/"
  start=$(date +%s)
  ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$root/fuzz/lsan.supp \
    UBSAN_OPTIONS=print_stacktrace=1 nice -n 19 "$build/fuzz/fuzz_$t" "$build/corpus/$t" \
    -max_total_time="$secs" -rss_limit_mb=2048 -timeout=30 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="$build/fuzz_$t-" > "$build/fuzz_$t.log" 2>&1
  rc=$?
  end=$(date +%s)
  execs=$(awk '/stat::number_of_executed_units:/ {print $2}' "$build/fuzz_$t.log")
  rss=$(awk '/stat::peak_rss_mb:/ {print $2}' "$build/fuzz_$t.log")
  echo "$t $((end - start)) s ${execs:-?} execs peak_rss ${rss:-?} MB rc=$rc"
done
