#!/usr/bin/env bash
# The before/after table of the fuzz findings (issue 24): runs one nurbsreg binary on every
# reproducer of tests/data/fuzz-regressions and prints, per finding, the exit status, the first
# line of stderr, the wall time and the peak RSS (/usr/bin/time -v).
#   tests/fuzz/findings_table.sh build/bin/nurbsreg [timeout-seconds]
set -uo pipefail
bin="$(realpath "$1")"
limit="${2:-120}"
cd "$(dirname "$0")/../.."
data=tests/data/fuzz-regressions
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
panel=examples/panel.json
"$bin" -q synth --model "$panel" --points 2000 --seed 1 --out "$work/scan.xyz" >/dev/null 2>&1
: >"$work/empty.xyz"
(cd "$work" && python3 "$OLDPWD/$data/gen_json_deg12_patch_blowup.py" 300)
run() {  # name, command...
  local name="$1"
  shift
  /usr/bin/time -v -o "$work/time.txt" timeout "$limit" "$@" >/dev/null 2>"$work/err.txt"
  local status=$?
  local wall rss
  wall=$(grep 'Elapsed (wall clock)' "$work/time.txt" | awk '{print $NF}')
  rss=$(grep 'Maximum resident set size' "$work/time.txt" | awk '{print $NF}')
  [ "$status" = 124 ] && status="timeout ${limit}s"
  local msg
  # The error line if there is one, else the first log line (what an accepted file printed),
  # without its timestamp; control bytes shown as ^X.
  msg=$(grep -v '^\[' "$work/err.txt" | head -1 | cut -c1-150 | cat -v)
  [ -z "$msg" ] && msg=$(head -1 "$work/err.txt" | sed 's/^\[[0-9:.]*\] //' | cut -c1-150 | cat -v)
  printf '| %s | %s | %s | %s | %s MB |\n' "$name" "$status" "$msg" "$wall" "$((rss / 1024))"
}
echo "| finding | exit | first stderr line | time | peak RSS |"
echo "| --- | --- | --- | --- | --- |"
for f in "$data"/pcd_*.pcd "$data"/ply_*.ply; do
  run "$(basename "$f")" "$bin" project --model "$panel" --points "$f" --out "$work/r.csv"
done
run pose_raw_escape_in_message.txt "$bin" align --model "$panel" --scan "$work/scan.xyz" \
  --init "$data/pose_raw_escape_in_message.txt" --out-pose "$work/p.txt"
for f in "$data"/step_*.step; do
  run "$(basename "$f")" "$bin" info --model "$f"
done
for f in "$data"/json_cp1e155_project_nonfinite.json "$data"/json_cp1e150_project_timeout.json; do
  run "$(basename "$f")" "$bin" project --model "$f" \
    --points "$data/json_cp1e150_project_timeout_points.xyz" --out "$work/r.csv"
done
run "deg12_300.json (gen_json_deg12_patch_blowup.py)" "$bin" info --model "$work/deg12_300.json"
run "empty.xyz (project)" "$bin" project --model "$panel" --points "$work/empty.xyz" --out "$work/r.csv"
