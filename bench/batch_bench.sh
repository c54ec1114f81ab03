#!/usr/bin/env bash
# Throughput of `nurbsreg batch` against one `nurbsreg align` process per frame, on synthetic
# scans of the freeform panel (examples/panel.json). Both write the same outputs (pose, aligned
# cloud, report) and the script checks that they are byte-identical (pose, aligned cloud).
#
#   bench/batch_bench.sh [FRAMES=50] [POINTS=200000] [THREADS=0 (all)]
#
# Environment: NURBSREG (binary, default build/bin/nurbsreg), MODEL (default
# examples/panel.json), MODE (align or project, default align). Scratch files go to a temporary
# directory that is removed at exit.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${NURBSREG:-build/bin/nurbsreg}
MODEL=${MODEL:-examples/panel.json}
MODE=${MODE:-align}
FRAMES=${1:-50}
POINTS=${2:-200000}
THREADS=${3:-0}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$WORK/scans" "$WORK/single" "$WORK/batch"

now() { date +%s.%N; }
# CPU seconds (user + system) of this shell's finished children, from `times` output saved by
# the main shell (a $(...) subshell would only see its own children).
cpu() { awk 'NR == 2 { gsub(/[ms]/, " "); print $1 * 60 + $2 + $3 * 60 + $4 }' "$1"; }

echo "generating $FRAMES frames of $POINTS points ..."
for ((i = 0; i < FRAMES; i++)); do
  name=$(printf 'frame_%04d' "$i")
  # A different pose and noise draw per frame, as a part re-fixtured on an inspection cell.
  pose="$(awk -v i="$i" 'BEGIN { printf "%.3f %.3f %.3f %.3f %.3f %.3f", \
      0.5 + 0.05 * (i % 7), -0.8 + 0.03 * (i % 5), 0.6, 0.2 * (i % 4), 0.4, -0.3 }')"
  "$BIN" -q synth --model "$MODEL" --points "$POINTS" --noise 0.02 --seed $((i + 1)) \
    --pose "$pose" --out "$WORK/scans/$name.pcd"
done

echo "one process per frame ..."
times >"$WORK/times0"
t0=$(now)
for f in "$WORK"/scans/*.pcd; do
  stem=$(basename "$f" .pcd)
  if [[ $MODE == align ]]; then
    "$BIN" -q align --threads "$THREADS" --model "$MODEL" --scan "$f" \
      --out-pose "$WORK/single/$stem.pose.txt" --aligned "$WORK/single/$stem.aligned.pcd" \
      --report "$WORK/single/$stem.report.json" >/dev/null
  else
    "$BIN" -q project --threads "$THREADS" --model "$MODEL" --points "$f" \
      --out "$WORK/single/$stem.projection.csv"
  fi
done
t1=$(now)
times >"$WORK/times1"

echo "batch ..."
"$BIN" -q batch --mode "$MODE" --threads "$THREADS" --model "$MODEL" --scans "$WORK/scans" \
  --out "$WORK/batch" >"$WORK/batch.txt"
t2=$(now)
times >"$WORK/times2"
cat "$WORK/batch.txt"

for f in "$WORK"/single/*; do
  [[ $f == *.report.json ]] && continue
  cmp -s "$f" "$WORK/batch/$(basename "$f")" || { echo "DIFFERENT: $(basename "$f")"; exit 1; }
done
echo "outputs identical (pose, aligned cloud / projection table)"

# Wall-clock time is what a user waits for; CPU time (user + system of all processes) is the
# work done, which a machine shared with other jobs measures more reliably.
awk -v mode="$MODE" -v n="$FRAMES" -v p="$POINTS" -v s="$(echo "$t1 - $t0" | bc)" \
  -v b="$(echo "$t2 - $t1" | bc)" -v cs="$(echo "$(cpu "$WORK/times1") - $(cpu "$WORK/times0")" | bc)" \
  -v cb="$(echo "$(cpu "$WORK/times2") - $(cpu "$WORK/times1")" | bc)" \
  'BEGIN {
     printf "%-28s %9s %9s %10s %12s %12s\n", "", "wall s", "cpu s", "frames/s", "points/s",
            "points/cpu-s";
     printf "%-28s %9.2f %9.2f %10.3f %12.0f %12.0f\n", mode ", one process/frame", s, cs,
            n / s, n * p / s, n * p / cs;
     printf "%-28s %9.2f %9.2f %10.3f %12.0f %12.0f\n", "batch", b, cb, n / b, n * p / b,
            n * p / cb;
     printf "speed-up: %.2fx wall-clock, %.2fx CPU time\n", s / b, cs / cb }'
