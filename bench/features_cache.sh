#!/usr/bin/env bash
# The model-features cache (README "Caches"): `nurbsreg -v align` from any pose of a 50,000-point
# synthetic scan, the first run building the model features (a miss) and the second reading
# them (a hit), ROUNDS times per model; prints the log's model-features time and the command's
# total, and checks that both runs wrote the same pose to the bit. `synth` loads the model
# first, which puts the converted model in the cache: the two runs differ only by the features.
#
#   bench/features_cache.sh [ROUNDS=3] [THREADS=2]
#
# Environment: NURBSREG (binary, default build/bin/nurbsreg), SHARED (default ../shared).
# Scratch files (scans, the cache) go to a temporary directory that is removed at exit.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${NURBSREG:-build/bin/nurbsreg}
SHARED=${SHARED:-../shared}
ROUNDS=${1:-3}
THREADS=${2:-2}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
export NURBSREG_CACHE_DIR="$WORK/cache"
unset NURBSREG_NO_CACHE

# name, model, scan noise (1e-4 of the model's diagonal, `nurbsreg info`)
models=("nist $SHARED/data/real/nist/nist_ctc_02_asme1_ap242-1.stp 0.117"
        "blade $SHARED/data/real/iea-15mw/IEA_15MW_CFD.stp 0.0117")
for entry in "${models[@]}"; do
  read -r name model noise <<<"$entry"
  "$BIN" -q synth --model "$model" --points 50000 --noise "$noise" \
    --pose "40 -70 120 3 -2 5" --seed 7 --out "$WORK/$name.pcd"
  for ((k = 1; k <= ROUNDS; k++)); do
    rm -f "$NURBSREG_CACHE_DIR"/*.nrbfeat
    for run in first second; do
      "$BIN" -v align --model "$model" --scan "$WORK/$name.pcd" --threads "$THREADS" \
        --out-pose "$WORK/$name-$run.pose" >/dev/null 2>"$WORK/$name-$run.err"
      features=$(grep -o 'model features: .* in [0-9.]* s$' "$WORK/$name-$run.err" |
        grep -o '[0-9.]* s$')
      outcome=$(grep -o '(hit\|(miss)\|(rebuilt)' "$WORK/$name-$run.err" | head -1 | tr -d '()')
      total=$(grep -o 'aligned 50000 points in [0-9.]* s' "$WORK/$name-$run.err" |
        grep -o '[0-9.]* s')
      echo "$name $run run ($outcome): model features $features, align $total," \
        "load average $(cut -d' ' -f1 /proc/loadavg)"
    done
    if cmp -s "$WORK/$name-first.pose" "$WORK/$name-second.pose"; then
      echo "$name: the same pose to the bit"
    else
      echo "$name: POSES DIFFER" >&2
      exit 1
    fi
  done
done
