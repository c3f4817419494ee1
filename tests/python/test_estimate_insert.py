# streetlight.Estimator / insert against streetlight-insert: the same KITTI insertion gives the
# same files bit for bit; bad input raises the exception type the module documents with the
# library's one-line message; the GIL is released while the library computes.
import os
import subprocess
import threading
import time

import numpy as np
import pytest

import streetlight as sl

from conftest import TRUCK


def street_image(h=48, w=96):
    """A small street-like picture: a blue sky above a grey road."""
    img = np.empty((h, w, 3), np.uint8)
    img[: h // 2] = (120, 160, 220)
    img[h // 2 :] = (90, 90, 90)
    return img


def test_kitti_estimate_and_insert_equal_the_tools_output_bit_for_bit(kitti, released, tool, tmp_path):
    common = ["--image", str(kitti / "000008.png"), "--intrinsics", str(kitti / "000008.txt"),
              "--lidar", str(kitti / "000008_velodyne.bin"), "--calib", str(kitti / "000008_calib.json"),
              "--object", str(TRUCK), "--at", "2.5,14", "--yaw", "70", "--sun-from-shadows",
              "--checkpoint", released]
    env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    subprocess.run([tool("streetlight-insert"), *common, "--out", str(tmp_path / "tool")], check=True, env=env,
                   stderr=subprocess.DEVNULL)

    photo = sl.load_photo(str(kitti / "000008.png"), intrinsics=str(kitti / "000008.txt"),
                          lidar=str(kitti / "000008_velodyne.bin"), calib=str(kitti / "000008_calib.json"))
    assert photo.depth_source == "lidar"
    light = sl.Estimator(released).estimate(photo.image, photo.intrinsics, depth=photo.depth)
    result = sl.insert(photo.image, photo.intrinsics, light, str(TRUCK), at=(2.5, 14), yaw=70, depth=photo.depth,
                       sun_from_shadows=True)
    result.save(str(tmp_path / "python"))
    for name in ("composite.png", "object_mask.png", "shadow_map.png", "sky.exr", "sky.png", "label.txt"):
        tool_bytes = (tmp_path / "tool" / name).read_bytes()
        assert (tmp_path / "python" / name).read_bytes() == tool_bytes, name
    import json
    j = json.loads((tmp_path / "tool" / "result.json").read_text())
    assert result.kitti_label == j["kitti_label"]
    assert result.lighting.sun_azimuth == j["sun"]["azimuth_deg"]
    assert result.lighting.sun_elevation == j["sun"]["elevation_deg"]
    assert result.lighting.sun_from_shadows["found"] == j["sun_from_shadows"]["found"]
    assert list(result.box2d) == j["box2d"]
    # The arrays are the pictures before 8-bit quantisation.
    assert result.composite.shape == photo.image.shape and result.composite.dtype == np.float32
    assert result.mask.shape == photo.image.shape[:2]


def test_photo_from_load_photo_is_the_image_the_tool_reads(kitti):
    photo = sl.load_photo(str(kitti / "000008.png"), intrinsics=str(kitti / "000008.txt"))
    assert photo.image.dtype == np.uint8 and photo.image.ndim == 3 and photo.image.shape[2] == 3
    assert photo.depth_source == "ground-plane"
    assert len(photo.intrinsics) == 4
    assert photo.intrinsics_source == "file"


def test_a_photo_without_intrinsics_takes_a_field_of_view(kitti):
    png = str(kitti / "000008.png")
    photo = sl.load_photo(png, fov=90.0)
    assert photo.intrinsics_source == "fov"
    w = photo.image.shape[1]
    assert photo.intrinsics == pytest.approx((w / 2, w / 2, w / 2, photo.image.shape[0] / 2))
    with pytest.raises(OSError, match="--fov"):  # a PNG has no EXIF focal length
        sl.load_photo(png)
    with pytest.raises(ValueError, match="fov"):
        sl.load_photo(png, fov=180.0)


def test_lighting_gives_the_sky_and_a_sun_in_the_camera_frame(released):
    est = sl.Estimator(released)
    light = est.estimate(street_image(), (60.0, 60.0, 48.0, 24.0))
    sky = light.sky()
    assert sky.dtype == np.float32 and sky.ndim == 3 and sky.shape[2] == 3 and sky.shape[1] > sky.shape[0]
    assert np.isfinite(sky).all()
    d = np.array(light.sun_direction)
    assert np.linalg.norm(d) == pytest.approx(1.0, abs=1e-9)
    # Level camera: camera y is down, so the camera frame's y is minus the world's.
    assert d[1] == pytest.approx(-light.sun_direction_world[1], abs=1e-12)
    moved = light.with_sun(azimuth=30.0, elevation=40.0)
    assert moved.sun_azimuth == pytest.approx(30.0, abs=1e-6)
    assert moved.sun_elevation == pytest.approx(40.0, abs=1e-6)
    # A float32 linear image is the same photo as its sRGB-ish 8-bit encoding.
    lin = (street_image().astype(np.float32) / 255.0) ** 2.2
    assert est.estimate(lin, (60.0, 60.0, 48.0, 24.0)).sun_azimuth == pytest.approx(light.sun_azimuth, abs=1.0)


def test_bad_image_dtype_and_shape_are_value_errors(released):
    est = sl.Estimator(released)
    k = (60.0, 60.0, 48.0, 24.0)
    with pytest.raises(ValueError, match=r"image: expected dtype uint8 \(sRGB\) or float32 \(linear\), got \(48, 96, 3\) int16"):
        est.estimate(street_image().astype(np.int16), k)
    with pytest.raises(ValueError, match=r"image: expected an H x W x 3 array .* got \(48, 96\) uint8"):
        est.estimate(street_image()[:, :, 0], k)
    with pytest.raises(ValueError, match=r"depth: \(10, 10\) float32 does not match the image's 48 x 96"):
        est.estimate(street_image(), k, depth=np.ones((10, 10), np.float32))


def test_bad_intrinsics_are_value_errors_with_the_librarys_message(released):
    est = sl.Estimator(released)
    with pytest.raises(ValueError, match=r"intrinsics: expected \(fx, fy, cx, cy\) or a 3 x 3 matrix, got \(60.0, 60.0, 48.0\)"):
        est.estimate(street_image(), (60.0, 60.0, 48.0))
    with pytest.raises(ValueError, match="intrinsics: principal point .* lies outside the 96x48 image"):
        est.estimate(street_image(), (60.0, 60.0, 480.0, 24.0))
    with pytest.raises(ValueError, match="intrinsics"):
        est.estimate(street_image(), (-60.0, 60.0, 48.0, 24.0))


def test_missing_files_are_file_not_found_errors_naming_the_file(released, tool, tmp_path):
    missing = str(tmp_path / "nowhere.safetensors")
    with pytest.raises(FileNotFoundError, match="nowhere.safetensors"):
        sl.Estimator(missing)
    with pytest.raises(FileNotFoundError, match="nowhere.png"):
        sl.load_photo(str(tmp_path / "nowhere.png"), intrinsics=str(tmp_path / "k.json"))
    light = sl.Estimator(released).estimate(street_image(), (60.0, 60.0, 48.0, 24.0))
    with pytest.raises(FileNotFoundError) as e:
        sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, str(tmp_path / "nowhere.glb"), at=(0, 8))
    # The library's one line, as the tool prints it after "error: ".
    out = subprocess.run([tool("streetlight-insert"), "--image", "x.png", "--intrinsics", "k.json", "--object",
                          str(tmp_path / "nowhere.glb"), "--at", "0,8", "--out", str(tmp_path / "o")],
                         capture_output=True, text=True)
    assert str(e.value) == "object file '" + str(tmp_path / "nowhere.glb") + "' does not exist"
    assert out.returncode == 2


def test_at_pixel_stands_the_object_on_the_pixels_ground(released):
    light = sl.Estimator(released).estimate(street_image(), (60.0, 60.0, 48.0, 24.0))
    # A level camera 1.65 m up: pixel (48, 40)'s centre sees the ground 1.65 * 60 / 16.5 = 6 m ahead.
    r = sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at_pixel=(48, 40), fast=True)
    assert r.placement["at"] == pytest.approx((0.5 / 60 * 6.0, 6.0), abs=1e-9)
    by_metres = sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at=r.placement["at"],
                          fast=True)
    assert by_metres.placement["world_x_m"] == pytest.approx(r.placement["world_x_m"], abs=1e-9)
    assert by_metres.placement["world_z_m"] == pytest.approx(r.placement["world_z_m"], abs=1e-9)
    with pytest.raises(ValueError, match="sees no surface"):
        sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at_pixel=(48, 3))
    with pytest.raises(ValueError, match="not both"):
        sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at=(0, 8), at_pixel=(48, 40))
    with pytest.raises(ValueError, match="is required"):
        sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car")


def test_label_class_names_the_object_in_its_kitti_label(released):
    light = sl.Estimator(released).estimate(street_image(), (60.0, 60.0, 48.0, 24.0))
    r = sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at=(0, 8), fast=True,
                  label_class="Truck")
    assert r.kitti_label.split()[0] == "Truck"
    default = sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at=(0, 8), fast=True)
    assert default.kitti_label.split()[0] == "Car"
    assert default.kitti_label.split()[1:] == r.kitti_label.split()[1:]
    with pytest.raises(ValueError, match="label_class 'Bus' is not a KITTI class"):
        sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at=(0, 8), label_class="Bus")


def test_bad_placement_is_a_value_error(released):
    light = sl.Estimator(released).estimate(street_image(), (60.0, 60.0, 48.0, 24.0))
    with pytest.raises(ValueError, match="behind the camera"):
        sl.insert(street_image(), (60.0, 60.0, 48.0, 24.0), light, "procedural:car", at=(0, -8))


def test_the_gil_is_released_during_an_estimate(released):
    est = sl.Estimator(released)
    image = np.ascontiguousarray(np.tile(street_image(), (4, 4, 1)))
    k = (240.0, 240.0, 192.0, 96.0)
    est.estimate(image, k)  # warm up
    ticks = []
    running = threading.Event()
    stop = threading.Event()

    def count():
        running.set()
        while not stop.is_set():
            ticks.append(time.perf_counter())

    t = threading.Thread(target=count)
    t.start()
    running.wait()
    start = time.perf_counter()
    est.estimate(image, k)
    end = time.perf_counter()
    stop.set()
    t.join()
    # Holding the GIL for the whole call, the counting thread could not run in its middle half.
    lo, hi = start + 0.25 * (end - start), start + 0.75 * (end - start)
    during = sum(lo <= x <= hi for x in ticks)
    assert during > 100, f"the counting thread ran {during} times in the middle of a {end - start:.3f} s estimate"
