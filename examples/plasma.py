"""A coronal loop arcade, built in NumPy and rendered by plume as blackbody emission.

A row of magnetic loops over a solar active region: each loop a half torus of hot plasma
standing on the surface (z = 0), their radii growing along the arcade and their planes
leaning, with a temperature that peaks at the loop tops. No file is written in between:
the arrays go to plume as they are. Run it from anywhere:

    python examples/plasma.py [output.png]

It writes the PNG (and an EXR beside it) and prints the render's statistics. The camera is
orthographic, as scientific views of a simulation box usually are.
"""

import sys

import numpy as np

import plume


def loop_arcade(n=(128, 64, 48), loops=9, tube=0.055):
    """Density and temperature (Kelvin) of `loops` half tori along x, on a grid of `n`
    voxels spanning [0, 2] × [-0.5, 0.5] × [0, 0.75] (world units)."""
    nx, ny, nz = n
    x = np.linspace(0.0, 2.0, nx)[:, None, None]
    y = np.linspace(-0.5, 0.5, ny)[None, :, None]
    z = np.linspace(0.0, 0.75, nz)[None, None, :]
    density = np.zeros(n)
    kelvin = np.zeros(n)
    for k in range(loops):
        t = (k + 0.5) / loops
        x0 = 0.15 + 1.7 * t  # the loop's place along the arcade
        radius = 0.22 + 0.2 * t  # larger loops further along
        lean = 0.35 * (t - 0.5)  # the loop planes lean, like a sheared arcade
        # Distance from each voxel to the loop: a circle of `radius` in the plane
        # x − x0 = lean · z, centred on the surface
        along = (x - x0) - lean * z
        ring = np.sqrt(y * y + z * z) - radius
        d2 = along * along + ring * ring
        profile = np.exp(-d2 / (tube * tube))
        height = np.clip(z / radius, 0.0, 1.0)  # 0 at the footpoints, 1 at the top
        density += 40.0 * profile * (1.0 - 0.6 * height)
        kelvin = np.maximum(kelvin, profile * (2500.0 + 5500.0 * height))
    kelvin[kelvin < 600.0] = 0.0
    return density.astype(np.float32), kelvin.astype(np.float32)


def main(out="plasma.png", width=480, height=270, spp=32):
    density, kelvin = loop_arcade()
    voxel = 2.0 / (density.shape[0] - 1)
    volume = plume.Volume.from_numpy(density, temperature=kelvin, voxel_size=voxel, origin=(0.0, -0.5, 0.0))
    scene = plume.Scene(
        volume=volume,
        # Optically thin, hot plasma: it emits and absorbs, and does not scatter
        medium={"albedo": 0.0},
        emission={"scale": 0.05},
        # An orthographic view, as a simulation box is shown: lengths do not shrink with depth
        camera={"from": [2.9, -1.9, 1.1], "at": [1.0, 0.0, 0.25], "up": [0.0, 0.0, 1.0],
                "projection": "orthographic", "ortho_width": 2.4, "width": width, "height": height},
        render={"spp": spp, "seed": 1},
    )
    image = plume.render(scene)
    image.write_png(out)
    image.write_exr(out.rsplit(".", 1)[0] + ".exr")
    s = image.stats
    print(f"{out}: {image.width}x{image.height}, {s['spp']} spp in {s['render_seconds']:.2f} s; leaves {volume.leaf_counts}")
    return image


if __name__ == "__main__":
    main(*sys.argv[1:2])
