#!/usr/bin/env bash
# The Python module's overhead, side by side with the tool: the README's KITTI insertion run by
# streetlight-insert and by examples/python/insert_truck.py (the same results bit for bit), in
# alternating rounds; prints each run's wall and CPU (user + sys) time and the medians. On a shared
# machine the CPU time is the steadier of the two.
# Usage: scripts/compare_python_tool.sh [BUILD_DIR] [ROUNDS]   (default build, 5)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}; rounds=${2:-5}
D=../shared/data/street/kitti_000008
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
tool=(); py=(); tool_cpu=(); py_cpu=()
cpu() { /usr/bin/time -f "%U %S" -o "$out/cpu" "$@" > /dev/null 2>&1; awk '{print $1 + $2}' "$out/cpu"; }
for ((i = 0; i < rounds; ++i)); do
  s=$(date +%s.%N)
  tool_cpu+=("$(cpu "$build/tools/streetlight-insert" --image $D/000008.png --intrinsics $D/000008.txt \
    --lidar $D/000008_velodyne.bin --calib $D/000008_calib.json \
    --object ../shared/data/models/CesiumMilkTruck.glb --at 2.5,14 --yaw 70 --sun-from-shadows \
    --out "$out/tool_$i")")
  m=$(date +%s.%N)
  py_cpu+=("$(PYTHONPATH="$build/python" cpu /usr/bin/python3 examples/python/insert_truck.py --out "$out/py_$i")")
  e=$(date +%s.%N)
  tool+=("$(echo "$m - $s" | bc)"); py+=("$(echo "$e - $m" | bc)")
  echo "round $i: tool ${tool[-1]} s (CPU ${tool_cpu[-1]} s), python ${py[-1]} s (CPU ${py_cpu[-1]} s)"
done
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
mt=$(median "${tool[@]}"); mp=$(median "${py[@]}")
echo "median wall: tool $mt s, python $mp s, python/tool $(echo "scale=3; $mp / $mt" | bc)"
ct=$(median "${tool_cpu[@]}"); cp=$(median "${py_cpu[@]}")
echo "median CPU: tool $ct s, python $cp s, python/tool $(echo "scale=3; $cp / $ct" | bc)"
