"""The Python API: scenes from files and keys, renders bit-identical to the command line's,
arrays bit-identical to VDB files, errors, progress, Ctrl-C and threads."""

import os
import signal
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import plume
from conftest import shared


def small(**extra):
    """Scene tables of a small render with scattering."""
    tables = {
        "medium": {"albedo": 0.7},
        "camera": {"width": 40, "height": 30},
        "render": {"spp": 4, "seed": 3},
    }
    tables.update(extra)
    return tables


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def blob(n=24, dtype=np.float32):
    """A smooth density ball and a hot core, with empty corners (skipped leaves)."""
    i = np.arange(n, dtype=np.float64) - (n - 1) / 2
    x, y, z = np.meshgrid(i, i * 1.1, i * 0.9, indexing="ij")
    r = np.sqrt(x * x + y * y + z * z) / (0.55 * n / 2)
    density = np.clip(1.0 - r, 0.0, None) * 2.0
    kelvin = np.where(density > 0, 500.0 + 2500.0 * np.clip(1.0 - 1.5 * r, 0.0, None), 0.0)
    return density.astype(dtype), kelvin.astype(dtype)


def test_scene_round_trips_through_toml(tmp_path, explosion):
    a = plume.Scene(volume={"file": str(explosion)}, **small())
    path = tmp_path / "scene.toml"
    a.write_toml(path)
    b = plume.Scene.from_toml(path)
    assert b.to_toml() == a.to_toml()
    ra, rb = plume.render(a), plume.render(b)
    assert np.array_equal(bits(ra.beauty), bits(rb.beauty))
    assert ra.beauty.shape == (30, 40, 4) and ra.beauty.dtype == np.float32
    assert ra.stats["spp"] == 4 and ra.stats["counters"]["samples"] == 40 * 30 * 4
    assert ra.beauty[..., 3].max() > 0.5, "the explosion covers pixels"


def test_python_and_the_command_line_write_the_same_pixels(tmp_path, explosion, plume_bin):
    scene = plume.Scene(volume={"file": str(explosion)}, output={"aovs": True}, **small())
    scene.write_toml(tmp_path / "scene.toml")
    cli = tmp_path / "cli.exr"
    subprocess.run(
        [plume_bin, "render", str(tmp_path / "scene.toml"), "-o", str(cli), "-q"],
        check=True,
        capture_output=True,
    )
    py = plume.render(scene)
    py.write_exr(tmp_path / "py.exr")
    for other in (plume.read_exr(cli), plume.read_exr(tmp_path / "py.exr")):
        assert np.array_equal(bits(other.beauty), bits(py.beauty))
        assert sorted(other.layers) == sorted(py.layers) and py.layers, "AOV layers"
        for name, layer in py.layers.items():
            assert np.array_equal(bits(other.layers[name]), bits(layer)), name
    assert py.layer_channels["emission"] == ["R", "G", "B"]
    py.write_png(tmp_path / "py.png")
    assert (tmp_path / "py.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_arrays_render_as_the_same_data_in_a_vdb_file(tmp_path, plume_bin):
    density, kelvin = blob()
    place = {"voxel_size": 0.05, "origin": (-0.6, -0.2, 0.1)}
    volume = plume.Volume.from_numpy(density, temperature=kelvin, **place)
    # Empty leaves are not stored: the ball leaves the corners out
    assert 0 < volume.leaf_counts["density"] < 27
    plume.write_vdb(tmp_path / "blob.vdb", {"density": density, "temperature": kelvin}, **place)
    grids = {g["name"]: g for g in plume.info(tmp_path / "blob.vdb")}
    assert grids["density"]["voxel_size"] == pytest.approx([0.05] * 3)
    from_arrays = plume.render(plume.Scene(volume=volume, **small()))
    from_file = plume.render(plume.Scene(volume={"file": str(tmp_path / "blob.vdb")}, **small()))
    assert from_arrays.beauty[..., 3].max() > 0.1
    assert np.array_equal(bits(from_arrays.beauty), bits(from_file.beauty))
    # The command line on the same file
    scene = plume.Scene(volume={"file": str(tmp_path / "blob.vdb")}, **small())
    scene.write_toml(tmp_path / "blob.toml")
    cli = tmp_path / "blob.exr"
    subprocess.run([plume_bin, "render", str(tmp_path / "blob.toml"), "-o", str(cli), "-q"], check=True)
    assert np.array_equal(bits(plume.read_exr(cli).beauty), bits(from_arrays.beauty))
    # Fortran order, float64 and a strided view give the same grids, so the same image
    for d, t in [
        (np.asfortranarray(density), np.asfortranarray(kelvin)),
        blob(dtype=np.float64),
        (np.pad(density, ((0, 0), (0, 0), (0, 24)))[:, :, :24], kelvin),
    ]:
        v = plume.Volume.from_numpy(d, temperature=t, **place)
        image = plume.render(plume.Scene(volume=v, **small()))
        assert np.array_equal(bits(image.beauty), bits(from_arrays.beauty))


def test_a_transform_places_the_grid_as_voxel_size_and_origin_do(tmp_path):
    density, kelvin = blob(16)
    m = np.diag([0.1, 0.1, 0.1, 1.0])
    m[:3, 3] = [0.2, -0.1, 0.3]
    a = plume.Volume.from_numpy(density, temperature=kelvin, transform=m)
    b = plume.Volume.from_numpy(density, temperature=kelvin, voxel_size=0.1, origin=(0.2, -0.1, 0.3))
    ra = plume.render(plume.Scene(volume=a, **small()))
    rb = plume.render(plume.Scene(volume=b, **small()))
    assert np.array_equal(bits(ra.beauty), bits(rb.beauty))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda d: plume.Volume.from_numpy(d[0]), r"shape \(16, 16\); a grid is \(nx, ny, nz\)"),
        (lambda d: plume.Volume.from_numpy(np.where(d == d.max(), np.nan, d)), "NaN or infinite"),
        (lambda d: plume.Volume.from_numpy(d, voxel_size=-0.1), "voxel_size"),
        (lambda d: plume.Volume.from_numpy(d.astype(np.int32)), "dtype int32"),
        (lambda d: plume.Volume.from_numpy(d, temperature=d[:4]), "differs from the density"),
        (lambda d: plume.Volume.from_numpy(d, transform=np.zeros((4, 4))), "transform"),
        (lambda d: plume.Volume.from_numpy(d, velocity=d), "vector grid"),
    ],
)
def test_bad_arrays_raise_input_errors(call, message):
    density, _ = blob(16)
    with pytest.raises(plume.InputError, match=message):
        call(density)


def test_scene_errors_name_the_key(explosion):
    with pytest.raises(plume.SceneError, match="medium.albedo"):
        plume.Scene(volume={"file": str(explosion)}, medium={"albedo": "grey"})
    with pytest.raises(plume.SceneError, match="camera.widht"):
        plume.Scene(volume={"file": str(explosion)}, camera={"widht": 3})
    with pytest.raises(plume.SceneError, match="camera.width"):
        plume.render(plume.Scene(volume={"file": str(explosion)}, camera={"width": 0}))
    with pytest.raises(plume.InputError, match="missing.vdb"):
        plume.render(plume.Scene(volume={"file": "missing.vdb"}))
    with pytest.raises(plume.SceneError, match="write them with Volume.write_vdb"):
        plume.Scene(volume=plume.Volume.from_numpy(blob(8)[0])).to_toml()
    assert issubclass(plume.SceneError, plume.Error) and issubclass(plume.RenderError, plume.Error)


def test_a_progress_callback_that_raises_stops_the_render(explosion):
    calls = []

    def progress(p):
        calls.append(p)
        raise ValueError("stop here")

    scene = plume.Scene(volume={"file": str(explosion)}, **small(render={"spp": 256, "seed": 1}))
    with pytest.raises(ValueError, match="stop here"):
        plume.render(scene, progress=progress)
    assert len(calls) == 1 and calls[0]["done"] < 256, calls
    # A callback that returns lets the render finish, and sees every pass
    seen = []
    plume.render(scene, progress=seen.append)
    assert seen[-1]["done"] == 256 and seen[-1]["fraction"] == 1.0


def test_two_threads_render_at_once_and_other_threads_run(explosion):
    scenes = [
        plume.Scene(volume={"file": str(explosion)}, **small(render={"spp": 16, "seed": s}))
        for s in (1, 2)
    ]
    alone = [plume.render(s).beauty for s in scenes]
    results = [None, None]
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(1)
            done.wait(0.001)

    ticker = threading.Thread(target=tick)
    ticker.start()

    def work(i):
        results[i] = plume.render(scenes[i]).beauty

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    done.set()
    ticker.join()
    for got, want in zip(results, alone):
        assert np.array_equal(bits(got), bits(want))
    assert len(ticks) > 5, "the ticker thread ran while rendering (the interpreter was released)"


def test_ctrl_c_stops_a_render_with_keyboard_interrupt(explosion):
    script = textwrap.dedent(
        f"""
        import sys, plume
        scene = plume.Scene(volume={{"file": {str(explosion)!r}}}, medium={{"albedo": 0.8}},
                            camera={{"width": 200, "height": 200}}, render={{"spp": 100000}})
        def progress(p):
            if p["done"] == 1:
                print("started", flush=True)
        try:
            plume.render(scene, progress=progress)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(0)
        print("finished", flush=True)
        sys.exit(1)
        """
    )
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "started"
    child.send_signal(signal.SIGINT)
    out, _ = child.communicate(timeout=120)
    assert out.strip() == "interrupted" and child.returncode == 0


def test_info_lists_grids_as_plume_info_json(plume_bin):
    smoke = shared("smoke/openvdb_org_smoke1.vdb")
    if not smoke.exists():
        pytest.skip(f"SKIPPED: {smoke} is missing (../shared beside the checkout)")
    grids = plume.info(smoke)
    cli = subprocess.run([plume_bin, "info", "--json", str(smoke)], check=True, capture_output=True, text=True)
    import json

    assert grids == json.loads(cli.stdout)
    assert grids[0]["name"] == "density" and grids[0]["active_voxels"] > 0
    with pytest.raises(plume.InputError):
        plume.info(os.devnull + ".vdb")


def test_the_plasma_example_renders(tmp_path):
    import importlib.util

    from conftest import ROOT

    spec = importlib.util.spec_from_file_location("plasma", ROOT / "examples" / "plasma.py")
    plasma = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(plasma)
    image = plasma.main(str(tmp_path / "plasma.png"), width=64, height=36, spp=2)
    assert (tmp_path / "plasma.png").stat().st_size > 0 and (tmp_path / "plasma.exr").exists()
    assert image.beauty[..., :3].max() > 0 and np.isfinite(image.beauty).all()


def test_damaged_files_are_read_in_a_child_and_raise_the_command_lines_error(tmp_path, plume_bin):
    smoke = shared("smoke/openvdb_org_smoke1.vdb")
    if not smoke.exists():
        pytest.skip(f"SKIPPED: {smoke} is missing (../shared beside the checkout)")
    cut = tmp_path / "cut.vdb"
    cut.write_bytes(smoke.read_bytes()[: smoke.stat().st_size // 3])
    cli = subprocess.run([plume_bin, "render", str(cut), "-o", str(tmp_path / "x.exr")], capture_output=True, text=True)
    assert cli.returncode == 3
    line = cli.stderr.strip().splitlines()[-1].removeprefix("plume: error: ")
    for reading in ({}, {"no_isolation": True}):
        with pytest.raises(plume.InputError) as e:
            plume.render(plume.Scene(volume={"file": str(cut)}, reading=reading, camera={"width": 8, "height": 8}))
        assert str(e.value) == line
    assert not (tmp_path / "x.exr").exists()


def test_one_frame_of_a_sequence_per_call():
    pattern = shared("sequence/openusd_smoke_######.vdb")
    if not shared("sequence/openusd_smoke_000002.vdb").exists():
        pytest.skip("SKIPPED: ../shared/data/sequence is missing")
    tables = {"camera": {"width": 16, "height": 16}, "render": {"spp": 1}}
    image = plume.render(plume.Scene(volume={"file": str(pattern)}, farm={"frames": "2"}, **tables))
    assert image.stats["frame"] == 2
    with pytest.raises(plume.SceneError, match="farm.frames: plume.render renders one frame, and 2 are given"):
        plume.render(plume.Scene(volume={"file": str(pattern)}, farm={"frames": "1-2"}, **tables))


def test_warnings_go_to_the_plume_logger(caplog):
    density, _ = blob(16)
    with caplog.at_level("INFO", logger="plume"):
        plume.render(plume.Scene(volume=plume.Volume.from_numpy(density), **small()))
    warnings = [r for r in caplog.records if r.name == "plume" and r.levelname == "WARNING"]
    assert any("no temperature or emission grid found" in r.getMessage() for r in warnings), caplog.records


def test_a_coloured_albedo_is_a_list(tmp_path, explosion):
    scene = plume.Scene(volume={"file": str(explosion)}, **small(medium={"albedo": [0.9, 0.5, 0.2]}))
    scene.write_toml(tmp_path / "coloured.toml")
    image = plume.render(scene)
    again = plume.render(plume.Scene.from_toml(tmp_path / "coloured.toml"))
    assert np.array_equal(bits(image.beauty), bits(again.beauty))
    grey = plume.render(plume.Scene(volume={"file": str(explosion)}, **small(medium={"albedo": 0.9})))
    # Red scatters as the grey 0.9 medium does on average; blue, with 0.2, less
    assert image.beauty[..., 2].sum() < grey.beauty[..., 2].sum()
    with pytest.raises(plume.SceneError, match="medium.albedo"):
        plume.Scene(volume={"file": str(explosion)}, medium={"albedo": [0.9, 0.5]})


def test_a_time_limit_returns_the_frame_reached_and_debug_pixels_are_refused(explosion):
    scene = plume.Scene(
        volume={"file": str(explosion)},
        farm={"time_limit": 1.0},
        **small(render={"spp": 1_000_000}),
    )
    image = plume.render(scene)
    assert image.stats["status"] == "time-limit" and 0 < image.stats["spp"] < 1_000_000
    assert image.beauty[..., 3].max() > 0.5
    with pytest.raises(plume.SceneError, match="render.debug_pixel"):
        plume.render(plume.Scene(volume={"file": str(explosion)}, render={"debug_pixel": "3,3,0"}))


def test_a_velocity_is_written_as_a_vector_grid(tmp_path):
    density, _ = blob(16)
    velocity = np.zeros(density.shape + (3,), dtype=np.float32)
    velocity[..., 0] = np.where(density > 0, 2.0, 0.0)
    volume = plume.Volume.from_numpy(density, velocity=velocity, voxel_size=0.1)
    volume.write_vdb(tmp_path / "moving.vdb")
    grids = {g["name"]: g for g in plume.info(tmp_path / "moving.vdb")}
    assert grids["velocity"]["type"].startswith("vec3")
    assert grids["velocity"]["max"] == pytest.approx(2.0)
    with pytest.raises(plume.InputError, match=r"velocity.y.*NaN or infinite"):
        bad = velocity.copy()
        bad[3, 3, 3, 1] = np.inf
        plume.Volume.from_numpy(density, velocity=bad)


def test_adaptive_sampling_and_the_error_layer(explosion):
    render = {"spp": 64, "seed": 3, "noise_threshold": 0.3, "min_spp": 8}
    image = plume.render(plume.Scene(volume={"file": str(explosion)}, **small(render=render)))
    # Every render has the error layer and the image's estimate
    assert image.layers["error"].shape == (30, 40, 3)
    assert image.stats["error_estimate"]["rel_rmse"] > 0
    # Pixels stopped at doubling checkpoints from min_spp, the background at the first
    counts = [b["spp"] for b in image.stats["spp_histogram"]]
    assert counts[0] == 8 and set(counts) <= {8, 16, 32, 64} and len(counts) > 1
    with pytest.raises(plume.SceneError, match="render.noise_threshold"):
        plume.render(plume.Scene(volume={"file": str(explosion)}, render={"noise_threshold": 0}))
