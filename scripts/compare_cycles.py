#!/usr/bin/env python3
"""plume against Blender Cycles 5.0.1 at equal CPU time.

Runs inside the venv that `scripts/compare-cycles.sh` makes (bpy==5.0.1, OpenEXR, numpy).
Cycles renders in this process through `bpy`; plume runs as a subprocess.

Matched conventions (both renderers, every render):
- the same camera, framed on the volume object's bounds: looking along +y, z up,
  horizontal field of view `--fov`, `--size`² pixels, box filter 1 pixel;
- sigma_t = density x 1 (Principled Volume: Density 1, the density grid as Density
  Attribute, Absorption Color black, so extinction = density and Color = albedo);
- Anisotropy = g = 0; volume bounces = plume's max depth = 64;
- emission in Cycles' convention (`--convention cycles`): blackbody of the Kelvin grid
  (Blackbody Intensity 1, white tint), or an emission grid driving Emission Strength
  (white Emission Color); not multiplied by density;
- trilinear reconstruction (Cycles' default for OpenVDB volumes, plume's default);
- black world, no denoising, no adaptive sampling, no clamping, fixed seed.

Metrics. Each renderer is measured against its own converged reference (`--ref-spp`):
relRMSE = sqrt(mean((I - R)^2)) / mean(R) over the RGB channels. The reference is
rendered with another seed than the rungs, so its noise is independent of theirs and adds
to the measured error; with Monte Carlo error ~ 1/spp in MSE, the measured relMSE is the
true one times (1 + N/N_ref), which is divided out ("corrected").
CPU time is what a render's samples cost. Every render's process CPU time is modelled as
o + c * spp: a fixed cost o that every render pays besides its samples (for Cycles with
persistent data, the film and output; for plume, loading the file) and a cost c per sample
per pixel, fitted over the ladder (its 1-spp render and rungs, through the 1-spp point:
c = sum((n - 1)(t_n - t_1)) / sum((n - 1)^2), o = t_1 - c). A rung's CPU is c * n. The
1-spp render is itself the ladder's first rung. Two simpler rules would do worse:
subtracting the whole 1-spp render leaves a rung of n spp charged for n - 1 samples (a
quarter off a 4-spp rung, a sixteenth off a 16-spp one), and each small rung's own time,
a difference of two renders of a few tenths of a second, varies widely between runs; the
per-sample cost each rung implies scatters about the fitted one (more for the shortest
rungs), and the fit averages that. The set-up (the first 1-spp
render: file load, scene sync, volume build) is reported apart. Each render runs
`--repeats` times (3) and the least CPU time counts: load from other processes only ever
adds time. The repeats go round the ladder, so a stretch of load slows one render of each
rung, not all of one.

Adaptive sampling (`--adaptive`). Each renderer also renders the noise thresholds
`--thresholds` with its own adaptive sampling (Cycles: Noise Threshold, automatic minimum
samples; plume: `--noise-threshold`, `min_spp` 16), both capped at `--adaptive-cap` spp.
An adaptive render's CPU is its least process CPU time less the fixed cost o fitted over
the renderer's uniform ladder, and its error is corrected for the reference's noise by
subtracting the reference's relMSE, estimated from the uniform ladder's longest rung as
relMSE(n) * n / N_ref. Rows: per Cycles threshold, Cycles' CPU and error, plume's error at
the same threshold (and its CPU), and plume's error at Cycles' CPU, interpolated along
plume's adaptive curve as for the ladders (the ratio the issue of efficiency asks for).

Both rules live in `scripts/budget.py` (standard library only; the test suite runs its
self-test).

At equal CPU: for each Cycles budget B (its CPU time at each rung of `--cycles-spp`),
plume's error is interpolated between the two rungs whose CPU times bracket B, linearly in
log error against log CPU, i.e. at the convergence rate measured there; only outside the
ladder is it scaled as sqrt(cpu/B) from the nearest end. With Owen-scrambled Sobol points
plume's error falls faster than 1/sqrt(spp) at a few samples per pixel (about as 1/spp
from 2 to 16 spp on the Mantaflow explosions), so scaling one rung by sqrt(cpu/B) across a
factor of 2 in time misstates the error at B by up to 1.4x, either way.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time

import numpy as np
import OpenEXR

from budget import at_budget, cpu_model

FILES = {
    "blender40": {
        "path": "explosion/blender_fluid_noise_0040.vdb",
        "density": "density_noise",
        "emission": ("grid", "flame_noise"),
        "about": "Blender's own Mantaflow cache, noise-upres frame 40: grid emission (flame_noise)",
    },
    "kelvin40": {
        "path": "explosion/mantaflow_explosion_kelvin_0040.vdb",
        "density": "density",
        "emission": ("blackbody", "temperature"),
        "about": "Mantaflow explosion frame 40, 192x192x256: blackbody of the Kelvin grid",
    },
    "r192": {
        "path": "explosion/mantaflow_explosion_r192n2_kelvin_0040.vdb",
        "density": "density",
        "emission": ("blackbody", "temperature"),
        "about": "the larger Mantaflow run, 288x288x384, frame 40: blackbody",
    },
}

# name -> albedo; emission-absorption uses plume's ray-march (zero variance per ray),
# scattering the paper's line-fnee
SETTINGS = {"ea": 0.0, "a0.5": 0.5, "a0.8": 0.8, "a0.95": 0.95}


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plume", default="target/release/plume")
    p.add_argument("--data", default="../shared/data")
    p.add_argument("--out", default="target/compare-cycles")
    p.add_argument("--files", default=",".join(FILES))
    p.add_argument("--settings", default=",".join(SETTINGS))
    p.add_argument("--size", type=int, default=128, help="image width and height")
    p.add_argument("--fov", type=float, default=40.0, help="horizontal field of view, degrees")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--max-depth", type=int, default=64)
    p.add_argument("--cycles-spp", default="16,64,256", help="Cycles' rungs; their CPU times are the budgets")
    p.add_argument("--plume-spp", default="2,4,8,16,32,64,256", help="plume's rungs above 1 spp (the 1-spp render is the first): dense where Cycles' budgets fall")
    p.add_argument("--ref-spp", type=int, default=4096, help="spp of each renderer's reference")
    p.add_argument("--repeats", type=int, default=3, help="renders of each rung (and of the 1-spp overhead render); the least CPU time counts")
    p.add_argument(
        "--cycles-from",
        metavar="DIR",
        help="rerun plume only: take Cycles' ladders, the cameras and plume's references from an earlier run's DIR (its results.json and *_plume_ref.exr)",
    )
    p.add_argument("--adaptive", action="store_true", help="also compare adaptive sampling at matched noise thresholds (settings default to a0.8)")
    p.add_argument("--thresholds", default="0.1,0.05,0.02,0.01", help="noise thresholds of --adaptive")
    p.add_argument("--adaptive-cap", type=int, default=1024, help="spp cap of the adaptive renders")
    p.add_argument("--quick", action="store_true", help="blender40 and kelvin40, ea and a0.8, short ladders and references")
    a = p.parse_args()
    if a.quick:
        a.files, a.settings = "blender40,kelvin40", "ea,a0.8"
        a.cycles_spp, a.plume_spp, a.ref_spp = "4,16", "2,4,8,16,64", 256
        a.thresholds, a.adaptive_cap = "0.1,0.05", 256
    if a.adaptive and "--settings" not in sys.argv:
        a.settings = "a0.8"
    a.files = a.files.split(",")
    a.settings = a.settings.split(",")
    for f in a.files:
        if f not in FILES:
            sys.exit(f"compare_cycles: --files: unknown file {f!r} (known: {', '.join(FILES)})")
    for s in a.settings:
        if s not in SETTINGS:
            sys.exit(f"compare_cycles: --settings: unknown setting {s!r} (known: {', '.join(SETTINGS)})")
    if a.repeats < 1:
        sys.exit(f"compare_cycles: --repeats: {a.repeats}: at least 1")
    a.thresholds = [float(t) for t in a.thresholds.split(",")]
    a.cycles_spp = [int(s) for s in a.cycles_spp.split(",")]
    a.plume_spp = [int(s) for s in a.plume_spp.split(",")]
    return a


def read_rgb(path):
    channels = OpenEXR.File(path).parts[0].channels
    if "RGBA" in channels:
        return channels["RGBA"].pixels[..., :3].astype(np.float64)
    if "RGB" in channels:
        return channels["RGB"].pixels.astype(np.float64)
    return np.stack([channels[c].pixels for c in ("R", "G", "B")], -1).astype(np.float64)


def rel_mse(img, ref):
    return float(np.mean((img - ref) ** 2) / np.mean(ref) ** 2)


# ---------------------------------------------------------------- Cycles (bpy)


class Cycles:
    """One volume file loaded in a fresh Blender scene, rendered with matched settings."""

    def __init__(self, args, spec):
        import bpy
        from mathutils import Vector

        self.bpy = bpy
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        path = os.path.abspath(os.path.join(args.data, spec["path"]))
        bpy.ops.object.volume_import(filepath=path, align="WORLD", location=(0, 0, 0))
        obj = bpy.context.active_object
        if obj is None or obj.type != "VOLUME":
            sys.exit(f"compare_cycles: Blender could not import {path}")
        obj.data.grids.load()
        self.material = bpy.data.materials.new("volume")
        obj.data.materials.append(self.material)
        self.spec = spec
        world = bpy.data.worlds.new("black")
        world.use_nodes = True
        world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
        scene.world = world
        # Camera on the bounds' centre, looking along +y, z up, the bounding sphere in view
        bpy.context.view_layer.update()
        corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
        lo = Vector([min(c[k] for c in corners) for k in range(3)])
        hi = Vector([max(c[k] for c in corners) for k in range(3)])
        centre, radius = (lo + hi) / 2, (hi - lo).length / 2
        distance = radius / math.sin(math.radians(args.fov) / 2)
        frm = centre - Vector((0.0, distance, 0.0))
        self.camera = {"from": list(frm), "at": list(centre), "up": [0.0, 0.0, 1.0], "fov": args.fov}
        cam_data = bpy.data.cameras.new("camera")
        cam_data.sensor_fit = "HORIZONTAL"
        cam_data.angle = math.radians(args.fov)
        cam_data.clip_end = 10 * distance + 10
        cam = bpy.data.objects.new("camera", cam_data)
        scene.collection.objects.link(cam)
        cam.location = frm
        cam.rotation_euler = (centre - frm).to_track_quat("-Z", "Y").to_euler()
        scene.camera = cam
        r, c = scene.render, scene.cycles
        r.engine = "CYCLES"
        c.device = "CPU"
        c.use_adaptive_sampling = False
        c.use_denoising = False
        c.sample_clamp_direct = 0.0
        c.sample_clamp_indirect = 0.0
        c.max_bounces = args.max_depth
        c.volume_bounces = args.max_depth
        c.transparent_max_bounces = args.max_depth
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
        c.seed = 0
        c.use_animated_seed = False
        r.resolution_x = r.resolution_y = args.size
        r.resolution_percentage = 100
        r.threads_mode = "FIXED"
        r.threads = args.threads
        r.film_transparent = False
        # Keep the synchronized scene between renders: set-up is paid once per setting
        r.use_persistent_data = True
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        scene.view_settings.exposure = 0.0
        scene.view_settings.gamma = 1.0
        r.image_settings.file_format = "OPEN_EXR"
        r.image_settings.color_depth = "32"

    def set_albedo(self, albedo):
        """Principled Volume with the conventions of the module docs."""
        self.set_principled((albedo, albedo, albedo))

    def set_principled(self, color, absorption=(0.0, 0.0, 0.0)):
        """Principled Volume with the conventions of the module docs, but for the
        scattering Color `color` and the Absorption Color `absorption` (black: grey
        extinction)."""
        m = self.material
        m.use_nodes = True
        nodes, links = m.node_tree.nodes, m.node_tree.links
        nodes.clear()
        out = nodes.new("ShaderNodeOutputMaterial")
        pv = nodes.new("ShaderNodeVolumePrincipled")
        pv.inputs["Color"].default_value = (*color, 1.0)
        pv.inputs["Density"].default_value = 1.0
        pv.inputs["Density Attribute"].default_value = self.spec["density"]
        pv.inputs["Absorption Color"].default_value = (*absorption, 1.0)
        pv.inputs["Anisotropy"].default_value = 0.0
        kind, grid = self.spec["emission"]
        if kind == "blackbody":
            pv.inputs["Blackbody Intensity"].default_value = 1.0
            pv.inputs["Blackbody Tint"].default_value = (1.0, 1.0, 1.0, 1.0)
            # Cycles multiplies the Temperature input by the attribute: 1 keeps Kelvin
            pv.inputs["Temperature"].default_value = 1.0
            pv.inputs["Temperature Attribute"].default_value = grid
        else:
            attr = nodes.new("ShaderNodeAttribute")
            attr.attribute_name = grid
            links.new(attr.outputs["Fac"], pv.inputs["Emission Strength"])
            pv.inputs["Emission Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        links.new(pv.outputs["Volume"], out.inputs["Volume"])

    def render(self, spp, path, seed=0, threshold=None):
        """Render `spp` samples to `path` with `seed` (adaptively to the noise `threshold`
        if one is given, `spp` the cap); returns the process CPU seconds it took."""
        scene = self.bpy.context.scene
        scene.cycles.seed = seed
        scene.cycles.samples = spp
        scene.cycles.use_adaptive_sampling = threshold is not None
        if threshold is not None:
            scene.cycles.adaptive_threshold = threshold
            scene.cycles.adaptive_min_samples = 0
        scene.render.filepath = path
        t0 = time.process_time()
        self.bpy.ops.render.render(write_still=True)
        return time.process_time() - t0


# ---------------------------------------------------------------- plume


def plume_render(args, spec, camera, albedo, spp, path, seed=0, threshold=None):
    """One plume render with the matched settings (adaptively to the noise `threshold` if
    one is given, `spp` the cap); returns its CPU seconds (stats)."""
    kind, grid = spec["emission"]
    cmd = [args.plume, "render", os.path.join(args.data, spec["path"]), "--density-grid", spec["density"], "--convention", "cycles"]
    cmd += ["--emission", "grid", "--emission-grid", grid] if kind == "grid" else ["--emission", "blackbody", "--temperature-grid", grid]
    cmd += ["--camera-from", ",".join(map(repr, camera["from"])), "--camera-at", ",".join(map(repr, camera["at"]))]
    cmd += ["--camera-up", "0,0,1", "--fov", repr(camera["fov"]), "--width", str(args.size), "--height", str(args.size)]
    cmd += ["--spp", str(spp), "--threads", str(args.threads), "--seed", str(seed), "--max-depth", str(args.max_depth), "--g", "0"]
    cmd += ["--method", "ray-march"] if albedo == 0.0 else ["--method", "line-fnee", "--albedo", repr(albedo)]
    if threshold is not None:
        cmd += ["--noise-threshold", repr(threshold)]
    stats = path + ".json"
    if os.path.exists(stats):
        os.remove(stats)  # plume appends one JSON line per render
    cmd += ["--stats", stats, "-o", path, "--overwrite", "-q"]
    subprocess.run(cmd, check=True)
    with open(stats) as f:
        return json.loads(f.read().splitlines()[-1])["cpu_seconds"]


# ---------------------------------------------------------------- measurement


# The references' seed; the rungs use seed 0.
REF_SEED = 1000


def least_cpu(render, spp, path, repeats):
    """The least CPU time of `repeats` renders of `spp` samples to `path` (fixed seeds: the
    same image each time). Load from other processes only ever adds time, so the least is
    the render's own cost; on a shared machine single small renders scatter widely."""
    return min(render(spp, path) for _ in range(repeats))


def ladder(render, spps, ref_spp, out, name, repeats, ref_from=None):
    """Set-up CPU (a first 1-spp render), then each rung's CPU and relRMSE against a
    `ref_spp` reference, corrected for the reference's noise. CPU follows the module docs'
    model o + c * spp, fitted over the 1-spp render (the first rung) and the rungs, each
    the least of `repeats` renders; a rung's CPU is c * n, its measured time less o is
    kept beside it."""
    spps = sorted(set(spps) - {1})
    if not spps:
        sys.exit(f"compare_cycles: {name}: the ladder needs a rung above 1 spp to measure the per-sample cost")
    setup = render(1, os.path.join(out, f"{name}_setup.exr"))
    if ref_from is not None:
        # An earlier run's reference (`--cycles-from`): (path, its spp, its CPU)
        ref_path, ref_spp, ref_cpu = ref_from
    else:
        ref_path = os.path.join(out, f"{name}_ref.exr")
        # Another seed than the rungs': with the same one a rung's samples would be the
        # first of the reference's, and the correction below assumes independent errors
        ref_cpu = render(ref_spp, ref_path, REF_SEED)
    ref = read_rgb(ref_path)
    # The repeats go round the ladder (every rung once, then again), so that a stretch of
    # load from other processes slows one render of several rungs, not every render of one
    ladder_spps = [1, *spps]
    paths = {spp: os.path.join(out, f"{name}_{'overhead' if spp == 1 else spp}.exr") for spp in ladder_spps}
    least = {spp: math.inf for spp in ladder_spps}
    for _ in range(repeats):
        for spp in ladder_spps:
            least[spp] = min(least[spp], render(spp, paths[spp]))
    per_sample, overhead = cpu_model(least)
    if per_sample <= 0.0:
        sys.exit(f"compare_cycles: {name}: the rungs took no measurable CPU time beyond a 1-spp render; use more spp or a larger --size")
    rungs = []
    for spp in ladder_spps:
        measured = rel_mse(read_rgb(paths[spp]), ref)
        rungs.append(
            {
                "spp": spp,
                "cpu": per_sample * spp,
                "cpu_measured": least[spp] - overhead,
                "relrmse_measured": math.sqrt(measured),
                "relrmse": math.sqrt(measured / (1 + spp / ref_spp)),
            }
        )
    return {"ref_path": ref_path, "setup_cpu": setup, "overhead_cpu": overhead, "cpu_per_spp": per_sample, "ref_spp": ref_spp, "ref_cpu": ref_cpu, "ref_mean": float(ref.mean()), "rungs": rungs}


def adaptive_series(render, thresholds, cap, ladder_result, out, name, repeats):
    """Each threshold's adaptive render against the ladder's reference: its CPU (least of
    `repeats`, less the ladder's fixed cost) and relRMSE less the reference's noise."""
    ref = read_rgb(ladder_result["ref_path"])
    longest = max(ladder_result["rungs"], key=lambda r: r["spp"])
    ref_noise = longest["relrmse"] ** 2 * longest["spp"] / ladder_result["ref_spp"]
    points = []
    for t in thresholds:
        path = os.path.join(out, f"{name}_t{t}.exr")
        cpu = min(render(cap, path, threshold=t) for _ in range(repeats))
        measured = rel_mse(read_rgb(path), ref)
        points.append(
            {
                "threshold": t,
                "cpu": max(cpu - ladder_result["overhead_cpu"], 1e-9),
                "relrmse_measured": math.sqrt(measured),
                "relrmse": math.sqrt(max(measured - ref_noise, 0.0)),
            }
        )
    return points


def adaptive_rows(cycles_points, plume_points):
    """Per Cycles threshold: plume at the same threshold, and plume at Cycles' CPU."""
    rows = []
    for c in cycles_points:
        same = next(p for p in plume_points if p["threshold"] == c["threshold"])
        pe = at_budget(plume_points, c["cpu"])
        rows.append({"threshold": c["threshold"], "cycles_cpu": c["cpu"], "cycles": c["relrmse"], "plume_cpu": same["cpu"], "plume_same_threshold": same["relrmse"], "plume": pe, "ratio": pe / c["relrmse"]})
    return rows


def main():
    args = parse_args()
    os.makedirs(args.out, exist_ok=True)
    results = []
    prior = None
    if args.cycles_from:
        # plume alone against an earlier run's Cycles ladders and plume references
        with open(os.path.join(args.cycles_from, "results.json")) as f:
            prior = {(r["file"], r["setting"]): r for r in json.load(f)["results"]}
        args.cycles_spp = [s for s in args.cycles_spp if all(any(r["spp"] == s for r in p["cycles"]["rungs"]) for p in prior.values())]
    for fname in args.files:
        spec = FILES[fname]
        cycles = Cycles(args, spec) if prior is None else None
        for sname in args.settings:
            albedo = SETTINGS[sname]
            name = f"{fname}_{sname}"
            ref_from = None
            if prior is None:
                print(f"compare_cycles: {name}: Cycles", file=sys.stderr, flush=True)
                cycles.set_albedo(albedo)
                camera = cycles.camera
                c = ladder(cycles.render, args.cycles_spp, args.ref_spp, args.out, f"{name}_cycles", args.repeats)
            elif (fname, sname) not in prior:
                sys.exit(f"compare_cycles: --cycles-from {args.cycles_from}: no {name} in its results.json")
            else:
                earlier = prior[(fname, sname)]
                camera, c = earlier["camera"], earlier["cycles"]
                p0 = earlier["plume"]
                ref_from = (os.path.join(args.cycles_from, f"{name}_plume_ref.exr"), p0["ref_spp"], p0["ref_cpu"])
            print(f"compare_cycles: {name}: plume", file=sys.stderr, flush=True)
            p = ladder(
                lambda spp, path, seed=0: plume_render(args, spec, camera, albedo, spp, path, seed),
                args.plume_spp,
                args.ref_spp,
                args.out,
                f"{name}_plume",
                args.repeats,
                ref_from,
            )
            entry = {}
            if args.adaptive:
                if cycles is None:
                    sys.exit("compare_cycles: --adaptive needs Cycles' adaptive renders: run it without --cycles-from")
                print(f"compare_cycles: {name}: adaptive", file=sys.stderr, flush=True)
                ca = adaptive_series(cycles.render, args.thresholds, args.adaptive_cap, c, args.out, f"{name}_cycles", args.repeats)
                pa = adaptive_series(
                    lambda spp, path, seed=0, threshold=None: plume_render(args, spec, camera, albedo, spp, path, seed, threshold),
                    args.thresholds,
                    args.adaptive_cap,
                    p,
                    args.out,
                    f"{name}_plume",
                    args.repeats,
                )
                entry = {"adaptive": {"cycles": ca, "plume": pa, "rows": adaptive_rows(ca, pa)}}
            rows = []
            for rung in (r for r in c["rungs"] if r["spp"] in args.cycles_spp):
                budget = rung["cpu"]
                pe = at_budget(p["rungs"], budget)
                rows.append({"cycles_spp": rung["spp"], "cpu": budget, "cycles": rung["relrmse"], "plume": pe, "ratio": pe / rung["relrmse"]})
            results.append({"file": fname, "setting": sname, "albedo": albedo, "camera": camera, "cycles": c, "plume": p, "rows": rows, "mean_ratio": p["ref_mean"] / c["ref_mean"], **entry})
            with open(os.path.join(args.out, "results.json"), "w") as f:
                json.dump({"args": {k: v for k, v in vars(args).items()}, "results": results}, f, indent=1)
    table = render_table(args, results)
    with open(os.path.join(args.out, "table.md"), "w") as f:
        f.write(table)
    print(table)


def render_table(args, results):
    lines = [
        f"{args.size}x{args.size}, {args.threads} threads, max depth {args.max_depth}, g 0; plume ray-march (EA) or line-fnee (scattering); "
        f"references {args.ref_spp} spp each; CPU seconds without set-up.",
        "",
        "| file | setting | CPU s | Cycles spp | Cycles relRMSE | plume relRMSE | plume ÷ Cycles | set-up CPU s (plume / Cycles) | image mean plume ÷ Cycles − 1 |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        for row in r["rows"]:
            lines.append(
                f"| {r['file']} | {r['setting']} | {row['cpu']:.2f} | {row['cycles_spp']} | {row['cycles']:.4f} | {row['plume']:.4f} | **{row['ratio']:.2f}** | "
                f"{r['plume']['setup_cpu']:.2f} / {r['cycles']['setup_cpu']:.2f} | {100 * (r['mean_ratio'] - 1):+.2f} % |"
            )
    if any("adaptive" in r for r in results):
        lines += [
            "",
            f"Adaptive sampling, capped at {args.adaptive_cap} spp (Cycles: Noise Threshold; plume: --noise-threshold); CPU seconds without the fixed cost.",
            "",
            "| file | setting | threshold | Cycles CPU s | Cycles relRMSE | plume CPU s | plume relRMSE | plume at Cycles' CPU | plume ÷ Cycles at equal CPU |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in (r for r in results if "adaptive" in r):
            for row in r["adaptive"]["rows"]:
                lines.append(
                    f"| {r['file']} | {r['setting']} | {row['threshold']} | {row['cycles_cpu']:.2f} | {row['cycles']:.4f} | {row['plume_cpu']:.2f} | "
                    f"{row['plume_same_threshold']:.4f} | {row['plume']:.4f} | **{row['ratio']:.2f}** |"
                )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
