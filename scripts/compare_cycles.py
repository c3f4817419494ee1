"""Optional comparison with Blender Cycles: renders the same scene as
`streetlight-render` with Cycles, and measures pixel noise from two seeds. Never used by the
library or CI; needs Debian's `blender` (3.4).

Render mode (one Cycles image per seed):
  blender -b --factory-startup -P scripts/compare_cycles.py -- render --glb TRUCK.glb
      --hdri SKY.hdr --cam X,Y,Z --look X,Y,Z --fov DEG --width W --height H --spp N
      --seeds 1,2 [--ground ALBEDO] [--rotate-deg D] [--max-depth D] --out DIR
  writes DIR/cycles_seed<S>.exr and prints one JSON line per image (seconds).
Stats mode (any number of labelled seed pairs):
  blender -b --factory-startup -P scripts/compare_cycles.py -- stats LABEL A.exr B.exr [LABEL A B ...]
  prints, per pair, the mean pixel value, the pixel noise sqrt(mean((a - b)^2) / 2) and the
  relative noise (noise / mean), over all pixels and channels, and the ratio of each noise to
  the first pair's.
Side-by-side mode (for looking at the images):
  blender -b --factory-startup -P scripts/compare_cycles.py -- png OUT.png EXPOSURE A.exr [B.exr ...]
  writes the images left to right as clip((EXPOSURE * L)^(1/2.2), 0, 1).

The scene follows streetlight-render's conventions: the glTF frame (+Y up) maps to Blender's
(x, -z, y); the ground plane sits at the models' lowest point, size max(200, 20 x diagonal),
a Principled BSDF of base colour ALBEDO, roughness 1, specular 0.5; the HDRI is rotated so
that panorama azimuth 0 looks down glTF -Z (render/equirect.h) and --rotate-deg D moves every
feature by +D of azimuth. Settings for an unbiased, like-for-like estimate: box pixel filter of
width 1, no adaptive sampling, no denoising, no clamping, no glossy filter, max bounces =
max_depth - 1 (streetlight's max_depth counts surface interactions), 'Standard' view, linear
32-bit EXR.
"""
import json
import math
import sys
import time

import numpy

numpy.bool = bool  # Blender 3.4's glTF importer still uses the alias removed in NumPy 1.24
import bpy  # noqa: E402
import mathutils  # noqa: E402


def parse_vec3(text):
    v = [float(x) for x in text.split(",")]
    if len(v) != 3:
        raise SystemExit(f"error: expected X,Y,Z, got '{text}'")
    return v


def gltf_to_blender(v):
    return mathutils.Vector((v[0], -v[2], v[1]))


def build_scene(a):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.import_scene.gltf(filepath=a["glb"])
    meshes = [o for o in scene.objects if o.type == "MESH"]
    lo = [1e30] * 3
    hi = [-1e30] * 3
    for o in meshes:
        for v in o.data.vertices:
            w = o.matrix_world @ v.co
            for k in range(3):
                lo[k], hi[k] = min(lo[k], w[k]), max(hi[k], w[k])
    if "ground" in a:
        diag = math.dist(lo, hi)
        size = max(200.0, 20.0 * diag)
        bpy.ops.mesh.primitive_plane_add(size=size, location=((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]))
        plane = bpy.context.active_object
        mat = bpy.data.materials.new("ground")
        mat.use_nodes = True
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        g = float(a["ground"])
        bsdf.inputs["Base Color"].default_value = (g, g, g, 1.0)
        bsdf.inputs["Roughness"].default_value = 1.0
        bsdf.inputs["Metallic"].default_value = 0.0
        bsdf.inputs["Specular"].default_value = 0.5
        plane.data.materials.append(mat)

    # World: the HDRI, looked up with rotation R_z(-90 + D): Blender's equirect centre column
    # looks down +X, streetlight's down glTF -Z = Blender +Y.
    world = bpy.data.worlds.new("sky")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(a["hdri"])
    env.interpolation = "Linear"
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(-90.0 + float(a.get("rotate-deg", 0))))
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    nt.nodes["Background"].inputs["Strength"].default_value = 1.0

    cam_data = bpy.data.cameras.new("cam")
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.angle = math.radians(float(a.get("fov", 50)))
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    pos, look = gltf_to_blender(parse_vec3(a["cam"])), gltf_to_blender(parse_vec3(a["look"]))
    cam.location = pos
    cam.rotation_euler = (look - pos).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam

    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = int(a["width"]), int(a["height"]), 100
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.color_mode = "RGB"
    r.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    c = scene.cycles
    c.device = "CPU"
    c.samples = int(a["spp"])
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    bounces = int(a.get("max-depth", 8)) - 1
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.transparent_max_bounces = bounces
    return scene


def render(a):
    scene = build_scene(a)
    for seed in [int(s) for s in a["seeds"].split(",")]:
        scene.cycles.seed = seed
        path = f"{a['out']}/cycles_seed{seed}.exr"
        scene.render.filepath = path
        t0 = time.time()
        bpy.ops.render.render(write_still=True)
        print(json.dumps({"cycles": path, "spp": int(a["spp"]), "seed": seed, "seconds": time.time() - t0,
                          "sampling_pattern": scene.cycles.sampling_pattern}))


def load(path):
    img = bpy.data.images.load(path)
    img.colorspace_settings.name = "Non-Color"
    px = list(img.pixels)
    w, h = img.size
    rgb = [px[4 * i + c] for i in range(w * h) for c in range(3)]
    bpy.data.images.remove(img)
    return rgb


def side_by_side(args):
    out, exposure, files = args[0], float(args[1]), args[2:]
    imgs = []
    for f in files:
        img = bpy.data.images.load(f)
        img.colorspace_settings.name = "Non-Color"
        imgs.append((img.size[0], img.size[1], list(img.pixels)))
        bpy.data.images.remove(img)
    h = imgs[0][1]
    w = sum(i[0] for i in imgs)
    px = [1.0] * (w * h * 4)
    x0 = 0
    for iw, ih, p in imgs:
        for y in range(min(h, ih)):
            for x in range(iw):
                for c in range(3):
                    v = max(0.0, exposure * p[4 * (y * iw + x) + c]) ** (1 / 2.2)
                    px[4 * (y * w + x0 + x) + c] = min(1.0, v)
        x0 += iw
    res = bpy.data.images.new("side_by_side", w, h)
    res.colorspace_settings.name = "Non-Color"
    res.pixels = px
    res.filepath_raw = out
    res.file_format = "PNG"
    res.save()


def stats(args):
    rows = []
    for k in range(0, len(args), 3):
        label, pa, pb = args[k:k + 3]
        a, b = load(pa), load(pb)
        if len(a) != len(b):
            raise SystemExit(f"error: {pa} and {pb} differ in size")
        mean = (sum(a) + sum(b)) / (2 * len(a))
        noise = math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)) / len(a) / 2)
        rows.append((label, mean, noise))
    for label, mean, noise in rows:
        print(json.dumps({"label": label, "mean": mean, "noise": noise, "relative_noise": noise / mean if mean else 0,
                          "noise_ratio_to_first": noise / rows[0][2] if rows[0][2] else 0,
                          "mean_ratio_to_first": mean / rows[0][1] if rows[0][1] else 0}))


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if not argv or argv[0] not in ("render", "stats", "png"):
        raise SystemExit(__doc__)
    if argv[0] == "png":
        side_by_side(argv[1:])
        return
    if argv[0] == "stats":
        stats(argv[1:])
        return
    a = {}
    it = iter(argv[1:])
    for k in it:
        a[k.lstrip("-")] = next(it)
    for key in ("glb", "hdri", "cam", "look", "width", "height", "spp", "seeds", "out"):
        if key not in a:
            raise SystemExit(f"error: --{key} is required")
    render(a)


main()
