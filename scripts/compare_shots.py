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
  --volume-scale 1.2,0.8,1 --volume-space object`.
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
    p.add_argument("--cases", default="coloured,dof,placed")
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


def set_case(cycles, a, case):
    """Cycles' material, camera and object transform for `case`; returns plume's flags
    for the same."""
    cam = cycles.bpy.context.scene.camera.data
    obj = next(o for o in cycles.bpy.data.objects if o.type == "VOLUME")
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
    results = []
    for case in a.cases:
        flags = set_case(cycles, a, case)
        cmd = [a.plume, "render", os.path.join(a.data, spec["path"]), "--density-grid", spec["density"], "--convention", "cycles"]
        cmd += ["--emission", "blackbody", "--temperature-grid", spec["emission"][1], "--up-axis", "z"]
        cmd += ["--camera-from", ",".join(map(repr, cam["from"])), "--camera-at", ",".join(map(repr, cam["at"])), "--camera-up", "0,0,1"]
        cmd += ["--width", str(a.size), "--height", str(a.size), "--spp", str(a.spp), "--threads", str(a.threads)]
        cmd += ["--max-depth", str(a.max_depth), "--g", "0", "--method", "line-fnee", "--overwrite", "-q"]
        c_runs, p_runs, _ = seed_pairs(cycles, a, case, cmd, flags, "compare_shots")
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
