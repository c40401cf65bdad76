#!/usr/bin/env python3
"""plume's external lights against Blender Cycles 5.0.1: image means.

Runs inside the venv of `scripts/compare-cycles.sh` (bpy==5.0.1, OpenEXR, numpy):
`bash scripts/compare-cycles.sh --lights`. A benchmark, not a test.

A shared Mantaflow explosion (density only: no emission, so the image is the lights'
scattered light), albedo 0.8, g 0, 64 bounces, matched as in `compare_cycles.py` (same
camera, box filter, no denoising/adaptive sampling/clamping), lit in turn by
- a sun lamp (Cycles Sun, Strength = irradiance W/m^2, Angle 0.53 deg) ==
  `--distant-light 'direction = [...], irradiance = S, angle = 0.53'`;
- a lat-long environment map (an asymmetric synthetic EXR written here, Environment
  Texture with Closest interpolation, Background Strength 1, visible to the camera) ==
  `--environment-map FILE --up-axis z`;
- a sphere light (Cycles Point lamp, Power P W, Radius r, soft falloff off) ==
  `--sphere-light 'position = [...], radius = r, power = P'`.
Each renderer runs `--spp` samples twice, with seeds 0 and 1; the table gives each image
mean (of both runs), their ratio, twice the standard error of the ratio (from the
difference of the two runs: per-pixel variance var(I0 - I1)/2, pixels independent), and the
means of four image quadrants (a wrong orientation shows there first).
"""

import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np
import OpenEXR

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_cycles import FILES, Cycles, read_rgb  # noqa: E402


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plume", default="target/release/plume")
    p.add_argument("--data", default="../shared/data")
    p.add_argument("--out", default="target/compare-lights")
    p.add_argument("--file", default="kelvin40", choices=list(FILES))
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--fov", type=float, default=40.0)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--max-depth", type=int, default=64)
    p.add_argument("--albedo", type=float, default=0.8)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--cases", default="sun,envmap,sphere")
    a = p.parse_args()
    a.cases = a.cases.split(",")
    return a


def write_map(path, width=256, height=128):
    """A smooth, asymmetric sky: warm glow towards +x low on the horizon, blue zenith,
    dark ground, a brighter patch towards -y. Rows from the top (+z)."""
    v = (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    theta = np.pi * v[:, None]
    phi = np.pi * (1.0 - 2.0 * u[None, :])
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta) + 0 * phi], -1)
    sky = np.where(d[..., 2:3] > 0, 1.0, 0.0)
    rgb = sky * (np.array([0.25, 0.4, 0.8]) * (0.3 + 0.7 * d[..., 2:3]))
    glow = np.exp(-((1 - d[..., 0:1]) * 6.0)) * np.array([3.0, 1.6, 0.6])
    patch = np.exp(-((1 + d[..., 1:2]) * 10.0)) * np.array([1.0, 1.0, 1.0]) * 2.0
    ground = (1 - sky) * np.array([0.05, 0.04, 0.03])
    img = (rgb + glow * (d[..., 2:3] > -0.1) + patch + ground).astype(np.float32)
    rgba = np.concatenate([img, np.ones((height, width, 1), np.float32)], -1)
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGBA": rgba}).write(path)


def cycles_lights(cycles, case, centre, radius, map_path):
    """Set Cycles' world and lamps for `case`; returns plume's flags for the same lights."""
    import bpy
    from mathutils import Vector

    scene = bpy.context.scene
    for o in [o for o in scene.objects if o.type == "LIGHT"]:
        bpy.data.objects.remove(o)
    world = scene.world
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    bg = nodes.new("ShaderNodeBackground")
    out = nodes.new("ShaderNodeOutputWorld")
    links.new(bg.outputs["Background"], out.inputs["Surface"])
    bg.inputs["Strength"].default_value = 0.0
    if case == "sun":
        d = Vector((0.4, 0.6, -0.7)).normalized()
        lamp = bpy.data.lights.new("sun", "SUN")
        lamp.energy = 3.0
        lamp.angle = math.radians(0.53)
        obj = bpy.data.objects.new("sun", lamp)
        scene.collection.objects.link(obj)
        obj.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
        return ["--distant-light", f"direction = [{d.x!r}, {d.y!r}, {d.z!r}], irradiance = 3.0, angle = 0.53"]
    if case == "envmap":
        tex = nodes.new("ShaderNodeTexEnvironment")
        tex.image = bpy.data.images.load(os.path.abspath(map_path))
        tex.image.colorspace_settings.name = "Linear Rec.709"
        tex.interpolation = "Closest"
        links.new(tex.outputs["Color"], bg.inputs["Color"])
        bg.inputs["Strength"].default_value = 1.0
        return ["--environment-map", os.path.abspath(map_path)]
    if case == "sphere":
        pos = Vector(centre) + Vector((-1.2 * radius, -0.8 * radius, 0.6 * radius))
        lamp = bpy.data.lights.new("sphere", "POINT")
        lamp.energy = 40000.0
        lamp.shadow_soft_size = 0.1 * radius
        lamp.use_soft_falloff = False
        obj = bpy.data.objects.new("sphere", lamp)
        scene.collection.objects.link(obj)
        obj.location = pos
        return ["--sphere-light", f"position = [{pos.x!r}, {pos.y!r}, {pos.z!r}], radius = {0.1 * radius!r}, power = 40000.0"]
    sys.exit(f"compare_lights: unknown case {case!r}")


def cycles_volume(cycles, albedo, density):
    """Principled Volume: density only, no emission."""
    m = cycles.material
    m.use_nodes = True
    nodes, links = m.node_tree.nodes, m.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    pv = nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    pv.inputs["Density"].default_value = 1.0
    pv.inputs["Density Attribute"].default_value = density
    pv.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    pv.inputs["Anisotropy"].default_value = 0.0
    pv.inputs["Blackbody Intensity"].default_value = 0.0
    pv.inputs["Emission Strength"].default_value = 0.0
    links.new(pv.outputs["Volume"], out.inputs["Volume"])


def seed_pairs(cycles, a, case, cmd, flags, label):
    """Cycles (as set up) and plume (`cmd` with the case's `flags`, all but its seed and
    output) each render `a.spp` samples with seeds 0 and 1 into `a.out`; returns both
    renderers' images and Cycles' CPU seconds. `label` names the script in progress lines."""
    print(f"{label}: {case}: Cycles", file=sys.stderr, flush=True)
    c_runs, p_runs, c_cpu = [], [], 0.0
    for seed in (0, 1):
        c_path = os.path.join(a.out, f"{case}_cycles_{seed}.exr")
        c_cpu += cycles.render(a.spp, c_path, seed=seed)
        c_runs.append(read_rgb(c_path))
    print(f"{label}: {case}: plume {' '.join(flags)}", file=sys.stderr, flush=True)
    for seed in (0, 1):
        p_path = os.path.join(a.out, f"{case}_plume_{seed}.exr")
        subprocess.run(cmd + flags + ["--seed", str(seed), "-o", p_path], check=True)
        p_runs.append(read_rgb(p_path))
    return c_runs, p_runs, c_cpu


def stats(runs):
    """Mean of two independent renders, the standard error of that mean (per-pixel
    variance from their difference), and the four quadrants' means."""
    img = 0.5 * (runs[0] + runs[1])
    var_pixel = np.var(runs[0] - runs[1], ddof=1) / 2.0
    se = math.sqrt(var_pixel / (2 * runs[0].size))
    h, w = img.shape[:2]
    q = [img[:h // 2, :w // 2], img[:h // 2, w // 2:], img[h // 2:, :w // 2], img[h // 2:, w // 2:]]
    return float(img.mean()), se, [float(x.mean()) for x in q]


def main():
    a = parse_args()
    os.makedirs(a.out, exist_ok=True)
    spec = FILES[a.file]
    cycles = Cycles(a, spec)
    cycles_volume(cycles, a.albedo, spec["density"])
    cam = cycles.camera
    centre = cam["at"]
    radius = math.dist(cam["from"], cam["at"]) * math.sin(math.radians(a.fov) / 2)
    map_path = os.path.join(a.out, "map.exr")
    write_map(map_path)
    results = []
    for case in a.cases:
        flags = cycles_lights(cycles, case, centre, radius, map_path)
        cmd = [a.plume, "render", os.path.join(a.data, spec["path"]), "--density-grid", spec["density"], "--emission", "none", "--up-axis", "z"]
        cmd += ["--camera-from", ",".join(map(repr, cam["from"])), "--camera-at", ",".join(map(repr, cam["at"])), "--camera-up", "0,0,1"]
        cmd += ["--fov", repr(a.fov), "--width", str(a.size), "--height", str(a.size), "--spp", str(a.spp), "--threads", str(a.threads)]
        cmd += ["--max-depth", str(a.max_depth), "--g", "0", "--albedo", repr(a.albedo), "--method", "line-fnee", "--overwrite", "-q"]
        c_runs, p_runs, c_cpu = seed_pairs(cycles, a, case, cmd, flags, "compare_lights")
        (cm, cse, cq), (pm, pse, pq) = stats(c_runs), stats(p_runs)
        results.append({"case": case, "flags": flags, "cycles_mean": cm, "cycles_se": cse, "plume_mean": pm, "plume_se": pse, "cycles_quadrants": cq, "plume_quadrants": pq, "cycles_cpu": c_cpu})
        with open(os.path.join(a.out, "results.json"), "w") as f:
            json.dump(results, f, indent=1)
    lines = [
        f"{a.file}, {a.size}x{a.size}, 2 x {a.spp} spp each, albedo {a.albedo}, g 0, max depth {a.max_depth}, no volume emission.",
        "",
        "| light | Cycles mean | plume mean | plume ÷ Cycles − 1 | ± (2σ of both means) | quadrants plume ÷ Cycles − 1 |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        rel = r["plume_mean"] / r["cycles_mean"] - 1
        sig = 2 * math.hypot(r["plume_se"], r["cycles_se"]) / r["cycles_mean"]
        quads = ", ".join(f"{100 * (p / c - 1):+.2f} %" for p, c in zip(r["plume_quadrants"], r["cycles_quadrants"]))
        lines.append(f"| {r['case']} | {r['cycles_mean']:.5f} | {r['plume_mean']:.5f} | **{100 * rel:+.2f} %** | {100 * sig:.2f} % | {quads} |")
    table = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "table.md"), "w") as f:
        f.write(table)
    print(table)


if __name__ == "__main__":
    main()
