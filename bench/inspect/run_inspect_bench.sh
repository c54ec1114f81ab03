#!/usr/bin/env bash
# bench/inspect: `nurbsreg inspect` on a 1 M-point scan of the NIST CTC-02 part, the report's
# size and the time until the page is interactive in headless Chromium; then CloudCompare's
# cloud-to-mesh distance (-C2M_DIST) on an OpenCASCADE tessellation of the same part, on the same
# aligned points, against nurbsreg's exact signed distances. bench/README.md "Inspection" has
# the figures.
#
# Usage: bench/inspect/run_inspect_bench.sh BUILD_DIR WORK_DIR [POINTS] [CHORD_TOLERANCE]
# Needs: the build's nurbsreg and bench/inspect/step_to_stl; chromium; CloudCompare; numpy for
# /usr/bin/python3 (Debian python3-numpy, which python3-open3d pulls in). Times: wall and CPU
# seconds (CPU says what a stage costs on a shared machine).
set -euo pipefail
build=$(realpath "$1")
work=$2
points=${3:-1000000}
chord=${4:-0.005}
here=$(dirname "$(realpath "$0")")
part=$(realpath "$here/../../../shared/data/real/nist/nist_ctc_02_asme1_ap242-1.stp")
nurbsreg="$build/bin/nurbsreg"
mkdir -p "$work"
cd "$work"

if [ ! -f scan.pcd ]; then
  # Noise 0.02 mm along the normal, a small scanner pose: ICP from the identity recovers it.
  "$nurbsreg" -q synth --model "$part" --points "$points" --noise 0.02 \
    --pose "0.3 -0.2 0.1 0.5 -0.3 0.4" --seed 2 --out scan.pcd
fi

echo "== nurbsreg inspect ($points points, 2 threads)"
rm -rf out
/usr/bin/time -f "inspect command: %e s wall, %U s user, %S s sys, %M KiB peak" \
  "$nurbsreg" -v inspect --model "$part" --scan scan.pcd --tolerance 0.05 --threads 2 \
  --out-dir out 2> inspect.log > inspect.out || { tail -3 inspect.log; exit 1; }
grep -E "inspect: |alignment .* s, inspection|inspect command" inspect.log | sed 's/^\[[^]]*\] debug //'
ls -l out | awk 'NR > 1 { printf "  %-20s %10d bytes\n", $9, $5 }'

echo "== report.html in headless Chromium (software WebGL, network off)"
page="file://$(realpath out/report.html)"
start=$(date +%s.%N)
chromium --headless --no-sandbox --use-gl=angle --use-angle=swiftshader --enable-unsafe-swiftshader \
  --proxy-server=127.0.0.1:9 --virtual-time-budget=60000 --dump-dom "$page" 2>/dev/null > dom.html
end=$(date +%s.%N)
grep -o '<div id="selfcheck"[^>]*>' dom.html | sed 's/^/  /'
echo "  chromium --dump-dom wall: $(echo "$end - $start" | bc) s (start-up, parse, decode, first frame)"

echo "== CloudCompare C2M on an OpenCASCADE tessellation (chord tolerance $chord mm)"
if [ ! -f part.stl ]; then
  "$build/bench/inspect/step_to_stl" "$part" part.stl "$chord" 0.05
fi
export QT_QPA_PLATFORM=offscreen
/usr/bin/time -f "CloudCompare load only: %e s wall, %U s user" \
  CloudCompare -SILENT -AUTO_SAVE OFF -O out/deviations.ply -O part.stl > /dev/null 2> cc_load.time
/usr/bin/time -f "CloudCompare load + C2M + save: %e s wall, %U s user" \
  CloudCompare -SILENT -AUTO_SAVE OFF -C_EXPORT_FMT PLY -PLY_EXPORT_FMT BINARY_LE \
  -O out/deviations.ply -O part.stl -C2M_DIST -SAVE_CLOUDS FILE cc_c2m.ply > cc.log 2> cc.time
tail -1 cc_load.time
tail -1 cc.time
/usr/bin/python3 "$here/compare_c2m.py" out/deviations.ply cc_c2m.ply
