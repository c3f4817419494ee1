#!/usr/bin/env bash
# The truck inserted into crops of four test-split LDR street panoramas (issue 39: "look at the
# pictures"), once with the released model's own sun and once with the sun of the panorama's
# label (sun_labels.csv), so that the two shadows can be compared with the photo's real ones.
# Usage: scripts/ldr_insertion_pictures.sh [--build DIR] [--out DIR] [--checkpoint CKPT]
# Writes OUT/<name>/{model,label}/composite.png and prints, per view, the model's sun, the
# label's sun (both in the crop camera's world frame: azimuth 0 = the view's forward direction,
# render/camera.h) and the angle between them. Needs ../shared/data (pano_ldr, models).
set -euo pipefail
cd "$(dirname "$0")/.."
build=build
out=runs/ldr_insertion
ckpt=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build="${2:?--build needs a folder}"; shift ;;
    --out) out="${2:?--out needs a folder}"; shift ;;
    --checkpoint) ckpt=(--checkpoint "${2:?--checkpoint needs a file}"); shift ;;
    -h|--help) sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "error: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
  shift
done
data=../shared/data
pano="$data/pano_ldr"
truck="$data/models/CesiumMilkTruck.glb"
for f in "$pano/sun_labels.csv" "$truck" "$build/tools/streetlight-crop" "$build/tools/streetlight-insert"; do
  [ -e "$f" ] || { echo "error: $f not found (the shared data beside the repository, and a build)" >&2; exit 2; }
done
mkdir -p "$out"

# name, panorama, view yaw, object X,Z, object yaw, scale. Pitch -15°, camera height 1.7 m, a
# 90° field of view at 640×360; the placements put the truck on the visible road surface.
# Four test-split street panoramas with hard shadows: the sun in front of the view (bux01, the
# people's shadows fall toward the camera), behind it (bux33: the cars' shadows fall away), and
# behind to one side (all4gis, aisle7).
views=(
  "bux01_yaw90 AMIRBEKSHAROPOV__BuxMTI_vr_tour__0-1.jpg 90 0.6,5 60 0.8"
  "bux33_yaw0 AMIRBEKSHAROPOV__BuxMTI_vr_tour__3-3.jpg 0 0.3,6 30 0.8"
  "all4gis_yaw-78 All4Gis__EquirectangularViewer__1.jpg -78 -0.6,4.0 20 0.6"
  "aisle7_yaw102 kairulin__panolens-360__aisle7.jpg 102 -1.5,11 150 1"
)
for v in "${views[@]}"; do
  read -r name file yaw at obj_yaw scale <<< "$v"
  dir="$out/$name"
  mkdir -p "$dir"
  crop_json=$("$build/tools/streetlight-crop" --panorama "$pano/$file" --out "$dir/view.png" --yaw "$yaw" \
    --pitch -15 --fov 90 --sun-labels "$pano/sun_labels.csv" --json 2>/dev/null)
  read -r label_az label_el < <(python3 -c '
import json, sys
c = json.loads(sys.argv[1]); s = c["sun"]
az = (s["azimuth_deg"] - float(sys.argv[2]) + 180.0) % 360.0 - 180.0
print(az, s["elevation_deg"])' "$crop_json" "$yaw")
  common=(--image "$dir/view.png" --intrinsics "$dir/view.json" --pitch -15 --camera-height 1.7
          --object "$truck" --at "$at" --yaw "$obj_yaw" --scale "$scale" "${ckpt[@]}")
  rm -rf "$dir/model" "$dir/label"
  "$build/tools/streetlight-insert" "${common[@]}" --out "$dir/model" > /dev/null
  "$build/tools/streetlight-insert" "${common[@]}" --sun-azimuth "$label_az" --sun-elevation "$label_el" \
    --out "$dir/label" > /dev/null
  python3 -c '
import json, math, sys
def d(az, el):
    a, e = math.radians(az), math.radians(el)
    return (math.cos(e) * math.sin(a), math.sin(e), -math.cos(e) * math.cos(a))
m = json.load(open(sys.argv[2] + "/model/result.json"))["sun"]
maz, mel = m["azimuth_deg"], m["elevation_deg"]
spread, prob = m.get("flip_spread_deg"), m.get("probability")
conf = ", ".join(f"{k} {v:.2f}" for k, v in (("flip spread", spread), ("probability", prob)) if v is not None)
laz, lel = float(sys.argv[3]), float(sys.argv[4])
cos = sum(p * q for p, q in zip(d(maz, mel), d(laz, lel)))
angle = math.degrees(math.acos(max(-1.0, min(1.0, cos))))
print(f"{sys.argv[1]}: model sun azimuth {maz:.1f} elevation {mel:.1f} ({conf}); "
      f"label azimuth {laz:.1f} elevation {lel:.1f}; angle {angle:.1f} deg")' "$name" "$dir" "$label_az" "$label_el"
done
echo "pictures: $out/*/{model,label}/composite.png"
