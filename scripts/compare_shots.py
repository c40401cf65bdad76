#!/usr/bin/env python3
"""plume against Blender Cycles 5.0.1 on shots that combine scene features: image means.

Runs inside the venv of `scripts/compare-cycles.sh` (bpy==5.0.1, OpenEXR, numpy):
`bash scripts/compare-cycles.sh --shots`. A benchmark, not a test.

A shared Mantaflow explosion with its blackbody emission (Cycles' convention), g 0,
64 bounces, matched as in `compare_cycles.py` (same camera placement, box filter, no
denoising, adaptive sampling or clamping), rendered as
- `coloured`: a coloured medium, Principled Volume Color = `--color` and Absorption
  Color = `--absorption`, so extinction differs per channel ==
  `--albedo R,G,B --absorption-color R,G,B`;
- `dof`: depth of field, grey albedo `--albedo-grey`: Cycles' camera with focal length
  `f` mm for the field of view on a 36 mm sensor (horizontal fit), F-stop `--fstop-scale`
  times the one that gives an aperture radius of 5 % of the camera distance, focused at
  0.75 of the distance to the volume's centre ==
  `--focal-length f --sensor-width 36 --fstop N --focus-distance d`;
- `placed`: grey albedo `--albedo-grey`, the volume object moved, rotated and scaled
  (Location 0.04 r, 0, 0.03 r with r the camera distance, Rotation XYZ Euler 10, 15, 20
  degrees, Scale 1.2, 0.8, 1; the Volume's render Space left at Blender's default, Object)
  and seen by the unmoved camera == `--volume-translate x,y,z --volume-rotate 10,15,20
  --volume-scale 1.2,0.8,1 --volume-space object`;
- `overlap`: two volumes that overlap, both showing the same VDB file: the imported
  object, unmoved, with the grey-albedo material (`--albedo-grey`, g 0), and a duplicate
  (its own copy of the Volume data-block, for a material of its own) placed at Location
  0.1 r, 0, 0.05 r, Rotation XYZ Euler 0, 0, 35 degrees, Scale 0.8 (render Space left at
  Object), with another Principled Volume, set up as the first's but for Color 0.5,
  Density 1.5 times, Anisotropy 0.5 and Blackbody Intensity 0.5 times the first's ==
  `--add-volume 'file = ..., translate = [x, y, z], rotate = [0, 0, 35], scale = 0.8,
  space = "object", medium = { density_scale = 1.5, albedo = 0.5, g = 0.5 },
  emission = { source = "blackbody", convention = "cycles", scale = 0.5 }'`. Cycles'
  blackbody strength is sigma * mix(1, T^4, Blackbody Intensity), so Intensity 0.5 is
  plume's emission scale 0.5 up to sigma / 2, about 1e-14 (against sigma T^4 / 2, about
  0.05 at 1500 K); Object space divides both the density and the emission by the scale
  0.8 on both sides. The duplicate is removed after the case.
Each renderer runs `--spp` samples twice, with seeds 0 and 1; the table gives each
channel's image mean (of both runs), their ratio, twice the standard error of the ratio
(from the difference of the two runs: per-pixel variance var(I0 - I1)/2, pixels
independent), and the means of four image quadrants (RGB together).
"""

import argparse
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_cycles import FILES, Cycles  # noqa: E402
from compare_lights import seed_pairs, stats  # noqa: E402


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plume", default="target/release/plume")
    p.add_argument("--data", default="../shared/data")
    p.add_argument("--out", default="target/compare-shots")
    p.add_argument("--file", default="kelvin40", choices=[k for k, v in FILES.items() if v["emission"][0] == "blackbody"])
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--fov", type=float, default=40.0)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--max-depth", type=int, default=64)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--color", default="0.9,0.6,0.3")
    p.add_argument("--absorption", default="0.2,0.5,0.8")
    p.add_argument("--albedo-grey", type=float, default=0.8)
    p.add_argument("--fstop-scale", type=float, default=1.0)
    p.add_argument("--cases", default="coloured,dof,placed,overlap")
    a = p.parse_args()
    a.cases = a.cases.split(",")
    a.color = [float(v) for v in a.color.split(",")]
    a.absorption = [float(v) for v in a.absorption.split(",")]
    return a


def lens(a, camera):
    """The `dof` case's thin lens: focal length (mm), F-stop, focus distance."""
    distance = math.dist(camera["from"], camera["at"])
    focal = 18.0 / math.tan(math.radians(a.fov) / 2)
    radius = 0.05 * distance
    return {"focal": focal, "fstop": a.fstop_scale * focal * 1e-3 / (2 * radius), "focus": 0.75 * distance}


# The `overlap` case's second volume: its Principled Volume's Color, and its Density and
# Blackbody Intensity as factors of the first's; its Anisotropy; its object transform
# (Location in camera distances r, Rotation XYZ Euler in degrees, uniform Scale).
OVERLAP = {"color": 0.5, "density": 1.5, "anisotropy": 0.5, "blackbody": 0.5,
           "location": (0.1, 0.0, 0.05), "rotation": (0.0, 0.0, 35.0), "scale": 0.8}


def toml_string(text):
    """A TOML basic string (JSON's escapes are TOML's)."""
    return json.dumps(text)


def add_second(cycles, a, obj, spec):
    """The `overlap` case: a duplicate of the volume object `obj` (same VDB file, its own
    copy of the Volume data-block so that it holds its own material) with the OVERLAP
    material and transform; returns plume's `--add-volume` value for the same volume."""
    bpy = cycles.bpy
    dup = obj.copy()
    dup.name = "overlap"
    dup.data = obj.data.copy()
    dup.data.name = "overlap"
    dup.data.grids.load()
    if dup.data.render.space != "OBJECT":
        sys.exit(f"compare_shots: overlap: the Volume's render Space is {dup.data.render.space!r}, not Blender's default 'OBJECT'")
    material = bpy.data.materials.new("overlap")
    dup.data.materials.clear()
    dup.data.materials.append(material)
    for collection in obj.users_collection:
        collection.objects.link(dup)
    # `set_principled` writes `cycles.material`: point it at the second material for the
    # conventions (density attribute, black absorption, Kelvin temperature, white tint),
    # then change what differs.
    first = cycles.material
    cycles.material = material
    try:
        cycles.set_principled((OVERLAP["color"],) * 3)
    finally:
        cycles.material = first
    pv = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
    pv.inputs["Density"].default_value *= OVERLAP["density"]
    pv.inputs["Anisotropy"].default_value = OVERLAP["anisotropy"]
    pv.inputs["Blackbody Intensity"].default_value *= OVERLAP["blackbody"]
    r = math.dist(cycles.camera["from"], cycles.camera["at"])
    move = tuple(f * r for f in OVERLAP["location"])
    dup.location, dup.rotation_mode = move, "XYZ"
    dup.rotation_euler = tuple(math.radians(d) for d in OVERLAP["rotation"])
    dup.scale = (OVERLAP["scale"],) * 3
    vec = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"  # noqa: E731
    # The first volume's density and emission scales are plume's defaults, 1: Density 1
    # and Blackbody Intensity 1 in `set_principled`.
    return ", ".join([
        f"file = {toml_string(os.path.join(a.data, spec['path']))}",
        f"density_grid = {toml_string(spec['density'])}",
        f"temperature_grid = {toml_string(spec['emission'][1])}",
        f"translate = {vec(move)}", f"rotate = {vec(OVERLAP['rotation'])}", f"scale = {OVERLAP['scale']!r}",
        'space = "object"',
        f"medium = {{ density_scale = {pv.inputs['Density'].default_value!r}, albedo = {OVERLAP['color']!r}, "
        f"g = {OVERLAP['anisotropy']!r} }}",
        f'emission = {{ source = "blackbody", convention = "cycles", scale = {pv.inputs["Blackbody Intensity"].default_value!r} }}',
    ])


def remove_others(cycles, keep):
    """Removes every volume object but `keep`, with the data-blocks and materials only
    they used: the scene as the cases before found it."""
    bpy = cycles.bpy
    for o in [o for o in bpy.data.objects if o.type == "VOLUME" and o != keep]:
        data, materials = o.data, [m for m in o.data.materials if m is not None]
        bpy.data.objects.remove(o, do_unlink=True)
        if data != keep.data and data.users == 0:
            bpy.data.volumes.remove(data)
        for m in materials:
            if m != cycles.material and m.users == 0:
                bpy.data.materials.remove(m)


def set_case(cycles, a, case, obj, spec):
    """Cycles' material, camera and object transform for `case` (`obj` the imported volume
    object); returns plume's flags for the same."""
    cam = cycles.bpy.context.scene.camera.data
    obj.location, obj.rotation_mode = (0.0, 0.0, 0.0), "XYZ"
    obj.rotation_euler, obj.scale = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
    cam.dof.use_dof = False
    cam.sensor_fit = "HORIZONTAL"
    cam.angle = math.radians(a.fov)
    rgb = lambda v: ",".join(repr(x) for x in v)  # noqa: E731
    if case == "coloured":
        cycles.set_principled(a.color, a.absorption)
        return ["--fov", repr(a.fov), "--albedo", rgb(a.color), "--absorption-color", rgb(a.absorption)]
    if case == "dof":
        cycles.set_albedo(a.albedo_grey)
        t = lens(a, cycles.camera)
        cam.lens_unit = "MILLIMETERS"
        cam.sensor_width = 36.0
        cam.lens = t["focal"]
        cam.dof.use_dof = True
        cam.dof.focus_distance = t["focus"]
        cam.dof.aperture_fstop = t["fstop"]
        cam.dof.aperture_blades = 0
        return ["--focal-length", repr(t["focal"]), "--sensor-width", "36", "--fstop", repr(t["fstop"]),
                "--focus-distance", repr(t["focus"]), "--albedo", repr(a.albedo_grey)]
    if case == "placed":
        cycles.set_albedo(a.albedo_grey)
        r = math.dist(cycles.camera["from"], cycles.camera["at"])
        move, turn, scale = (0.04 * r, 0.0, 0.03 * r), (10.0, 15.0, 20.0), (1.2, 0.8, 1.0)
        obj.location = move
        obj.rotation_euler = tuple(math.radians(d) for d in turn)
        obj.scale = scale
        return ["--fov", repr(a.fov), "--albedo", repr(a.albedo_grey), "--volume-translate", rgb(move),
                "--volume-rotate", rgb(turn), "--volume-scale", rgb(scale), "--volume-space", "object"]
    if case == "overlap":
        cycles.set_albedo(a.albedo_grey)
        return ["--fov", repr(a.fov), "--albedo", repr(a.albedo_grey), "--add-volume", add_second(cycles, a, obj, spec)]
    sys.exit(f"compare_shots: unknown case {case!r}")


def channel_stats(runs):
    """Per channel: mean of two independent renders and the standard error of that mean
    (`compare_lights.stats` of the channel); the four quadrants' means (RGB)."""
    per = [stats([r[..., c] for r in runs]) for c in range(3)]
    return [m for m, _, _ in per], [se for _, se, _ in per], stats(runs)[2]


def main():
    a = parse_args()
    os.makedirs(a.out, exist_ok=True)
    spec = FILES[a.file]
    cycles = Cycles(a, spec)
    cam = cycles.camera
    obj = next(o for o in cycles.bpy.data.objects if o.type == "VOLUME")
    results = []
    for case in a.cases:
        try:
            flags = set_case(cycles, a, case, obj, spec)
            cmd = [a.plume, "render", os.path.join(a.data, spec["path"]), "--density-grid", spec["density"], "--convention", "cycles"]
            cmd += ["--emission", "blackbody", "--temperature-grid", spec["emission"][1], "--up-axis", "z"]
            cmd += ["--camera-from", ",".join(map(repr, cam["from"])), "--camera-at", ",".join(map(repr, cam["at"])), "--camera-up", "0,0,1"]
            cmd += ["--width", str(a.size), "--height", str(a.size), "--spp", str(a.spp), "--threads", str(a.threads)]
            cmd += ["--max-depth", str(a.max_depth), "--g", "0", "--method", "line-fnee", "--overwrite", "-q"]
            c_runs, p_runs, _ = seed_pairs(cycles, a, case, cmd, flags, "compare_shots")
        finally:
            remove_others(cycles, obj)
        (cm, cse, cq), (pm, pse, pq) = channel_stats(c_runs), channel_stats(p_runs)
        results.append({"case": case, "flags": flags, "cycles_means": cm, "cycles_se": cse, "plume_means": pm, "plume_se": pse,
                        "cycles_quadrants": cq, "plume_quadrants": pq})
        with open(os.path.join(a.out, "results.json"), "w") as f:
            json.dump(results, f, indent=1)
    lines = [
        f"{a.file}, {a.size}x{a.size}, 2 x {a.spp} spp each, blackbody emission (Cycles' convention), g 0, max depth {a.max_depth}.",
        "",
        "| shot | channel | Cycles mean | plume mean | plume ÷ Cycles − 1 | ± (2σ of both means) |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        for c, name in enumerate("RGB"):
            cm, pm = r["cycles_means"][c], r["plume_means"][c]
            sig = 2 * math.hypot(r["plume_se"][c], r["cycles_se"][c]) / cm
            lines.append(f"| {r['case']} | {name} | {cm:.5f} | {pm:.5f} | **{100 * (pm / cm - 1):+.2f} %** | {100 * sig:.2f} % |")
    lines += ["", "| shot | quadrants plume ÷ Cycles − 1 (RGB) |", "|---|---|"]
    for r in results:
        quads = ", ".join(f"{100 * (p / c - 1):+.2f} %" if c > 0 else f"{p:.3g} vs 0" for p, c in zip(r["plume_quadrants"], r["cycles_quadrants"]))
        lines.append(f"| {r['case']} | {quads} |")
    table = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "table.md"), "w") as f:
        f.write(table)
    print(table)


if __name__ == "__main__":
    main()
