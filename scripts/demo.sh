#!/usr/bin/env bash
# The main job on bundled data, from a fresh clone: install, build, then align a synthetic scan
# of the example panel (moved 5 degrees / 5 mm, with 0.02 mm noise) to the CAD model and print
# the pose, the RMS and the deviation summary.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
./scripts/build.sh >/dev/null
bin=build/bin/nurbsreg
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

echo "== nurbsreg info --model examples/panel.json"
$bin info --model examples/panel.json
echo
echo "== nurbsreg synth: 200,000 points, noise 0.02 mm, scanner pose 3/-2/4 deg, (3, -2, 2) mm"
$bin synth --model examples/panel.json --points 200000 --noise 0.02 --seed 7 \
  --pose "3 -2 4 3 -2 2" --out "$out/scan.pcd" --out-pose "$out/true_pose.txt"
echo
echo "== nurbsreg align --model examples/panel.json --scan scan.pcd"
$bin align --model examples/panel.json --scan "$out/scan.pcd" --out-pose "$out/pose.txt" \
  --report "$out/report.json" --aligned "$out/aligned.pcd"
echo
echo "true pose (from synth):"
sed 's/^/  /' "$out/true_pose.txt"
echo
echo "== nurbsreg project: exact closest points of the aligned scan"
$bin project --model examples/panel.json --points "$out/aligned.pcd" --out "$out/deviations.csv"
head -3 "$out/deviations.csv"
