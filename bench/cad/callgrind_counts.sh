#!/bin/bash
# Instructions per point of Projector::project for each model (issue 26; see bench/README.md,
# "Real CAD models"): near and mixed points, the warm set's hinted frame (the near points moved by
# 1e-4 of the diagonal after a certifying frame) and every projection pass of an alignment, with
# the answers' checksums (a change that should not move any result must print the same ones);
# `alignall` counts the whole alignment (the finder's hints and atlas lookups too) and prints its
# pose checksum.
#   bench/cad/callgrind_counts.sh TAG PROJECTION_COUNTS DIR_OF_JSON_MODELS OUT_DIR [POINTS [SETS]]
# SETS: which counts, space-separated (default "near mixed warm align"; also "alignall").
# The JSON models come from `nurbsreg convert` (bearing.json, hammer.json, IEA_15MW_CFD.json,
# nist_ctc_02_asme1_ap242-1.json, linkrods.json).
set -euo pipefail
TAG=$1 BIN=$2 MODELS=$3 OUT=$4 N=${5:-2000} SETS=${6:-near mixed warm align}
mkdir -p "$OUT"
count() {  # name out-file args...
  local name=$1 out=$2
  shift 2
  # The warm set: only its hinted frame (the certifying frame before it is not counted).
  local toggle='nurbsreg::engine::Projector::project(*'
  [[ $name == *warm ]] && toggle='*warm_frame*'
  [[ $name == *alignall ]] && toggle='*align_scan*'
  valgrind --tool=callgrind --collect-atstart=no \
    --toggle-collect="$toggle" --callgrind-out-file="$out.cg" \
    "$BIN" "$@" >"$out.txt" 2>"$out.err"
  local ir
  ir=$(grep -E "^summary:|^totals:" "$out.cg" | head -1 | awk '{print $2}')
  echo "$TAG $name Ir=$ir per_point=$((ir / N)) $(grep -hE 'checksum' "$out.txt" | tr '\n' ' ')"
}
for m in bearing hammer IEA_15MW_CFD nist_ctc_02_asme1_ap242-1 linkrods; do
  for set in $SETS; do
    case $set in
      near | mixed | warm)
        count "$m $set" "$OUT/$TAG.$m.$set" "$MODELS/$m.json" --points "$N" --sets "$set" ;;
      align | alignall)
        count "$m $set" "$OUT/$TAG.$m.$set" "$MODELS/$m.json" --points 100 --sets none --align "$N" ;;
    esac
  done
done
