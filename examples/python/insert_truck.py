#!/usr/bin/env python3
"""Estimates the light of the shared KITTI frame and inserts the Cesium milk truck, from Python.

The same insertion as the README's streetlight-insert command (--at 2.5,14 --yaw 70
--sun-from-shadows, lidar depth), bit for bit. Run from the repository after the build:

    PYTHONPATH=build/python python3 examples/python/insert_truck.py [--out runs/kitti_python]

Writes composite.png, object_mask.png, shadow_map.png, sky.exr, sky.png and label.txt.
"""
import argparse
import pathlib
import sys
import time

import streetlight

root = pathlib.Path(__file__).resolve().parents[2]
shared = root.parent / "shared" / "data"

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--frame", default=str(shared / "street" / "kitti_000008"), help="KITTI frame folder")
parser.add_argument("--object", default=str(shared / "models" / "CesiumMilkTruck.glb"), help="glTF model")
parser.add_argument("--out", default="runs/kitti_python", help="output folder")
args = parser.parse_args()

frame = pathlib.Path(args.frame)
start = time.perf_counter()
try:
    photo = streetlight.load_photo(str(frame / "000008.png"), intrinsics=str(frame / "000008.txt"),
                                   lidar=str(frame / "000008_velodyne.bin"), calib=str(frame / "000008_calib.json"))
    estimator = streetlight.Estimator()  # the released model, models/streetlight.safetensors
    lighting = estimator.estimate(photo.image, photo.intrinsics, depth=photo.depth)
    result = streetlight.insert(photo.image, photo.intrinsics, lighting, args.object, at=(2.5, 14), yaw=70,
                                depth=photo.depth, sun_from_shadows=True)
except (OSError, ValueError) as e:
    sys.exit(f"error: {e}")
result.save(args.out)
light = result.lighting
print(f"network's sun: azimuth {lighting.sun_azimuth:.1f}°, elevation {lighting.sun_elevation:.1f}°")
print(f"sun from the photo's shadows: azimuth {light.sun_azimuth:.1f}°, elevation {light.sun_elevation:.1f}°")
print(f"KITTI label: {result.kitti_label}")
print(f"wrote {args.out} in {time.perf_counter() - start:.2f} s")
