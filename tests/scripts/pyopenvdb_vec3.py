"""OpenVDB's own view of vector grids, for tests/vec3_grids.rs (run with /usr/bin/python3,
where Debian's python3-openvdb installs the `pyopenvdb` module).

    pyopenvdb_vec3.py write OUT.vdb     write the synthetic file described in write()
    pyopenvdb_vec3.py dump FILE GRID    print GRID as JSON (see dump())

Exits 3 when pyopenvdb cannot be imported, so that the test can skip loudly.
"""

import json
import math
import sys

try:
    import pyopenvdb as vdb
except ImportError as e:
    print(f"pyopenvdb unavailable: {e}", file=sys.stderr)
    sys.exit(3)


def add_topology(grid, value):
    """Voxels, partial fills (voxels in leaves) and whole-node fills (active tiles).

    `value(v)` maps a vector to what the grid stores (the vector itself or one component).
    """
    acc = grid.getAccessor()
    acc.setValueOn((1, 2, 3), value((1.0, -2.0, 3.5)))
    acc.setValueOn((-9, 0, 4), value((0.25, 0.5, -0.75)))
    acc.setValueOn((100, -100, 7), value((-1.0, 0.0, 1.0)))
    acc.setValueOff((2, 2, 3), value((4.0, 4.0, 4.0)))  # inactive voxel keeps its value
    grid.fill((0, 16, 0), (3, 19, 3), value((9.0, -9.0, 0.125)), True)  # 64 voxels in a leaf
    grid.fill((32, 0, 0), (47, 15, 15), value((1.5, -2.5, 3.5)), True)  # 8 level-1 tiles
    grid.fill((128, 0, 0), (255, 127, 127), value((-0.5, 0.75, 2.0)), True)  # 1 level-2 tile


def write(out):
    """`vel`: a Vec3SGrid, background (0.5, 0, -0.5), voxel size 0.25, with add_topology's
    voxels and tiles. `vel_x`: a FloatGrid of the same topology holding vel's x component
    (so that its leaves and blocks can be compared with the vector read's)."""
    vel = vdb.Vec3SGrid((0.5, 0.0, -0.5))
    vel.name = "vel"
    vel.transform = vdb.createLinearTransform(voxelSize=0.25)
    add_topology(vel, lambda v: v)
    vel_x = vdb.FloatGrid(0.5)
    vel_x.name = "vel_x"
    vel_x.transform = vdb.createLinearTransform(voxelSize=0.25)
    add_topology(vel_x, lambda v: v[0])
    vdb.write(out, grids=[vel, vel_x])


def dump(path, name):
    """JSON: type, active_voxels, leaf_count (file leaves), background, `voxels` (every
    value inside a leaf, active or not: [i, j, k, x, y, z, active]), `tiles` (active tiles:
    [min, max, value]) and the magnitude sum, min and max over active values, tiles
    counted once per voxel."""
    grid = vdb.read(path, name)
    voxels, tiles = [], []
    mag_sum, mag_min, mag_max = 0.0, math.inf, -math.inf
    for item in grid.iterAllValues():
        value = [float(c) for c in item["value"]]
        if item["count"] == 1:
            voxels.append(list(item["min"]) + value + [bool(item["active"])])
        elif item["active"]:
            tiles.append([list(item["min"]), list(item["max"]), value])
        if item["active"]:
            magnitude = math.sqrt(sum(c * c for c in value))
            mag_sum += magnitude * item["count"]
            mag_min, mag_max = min(mag_min, magnitude), max(mag_max, magnitude)
    print(json.dumps({
        "type": grid.valueTypeName,
        "active_voxels": grid.activeVoxelCount(),
        "leaf_count": grid.leafCount(),
        "background": [float(c) for c in grid.background],
        "voxels": voxels,
        "tiles": tiles,
        "magnitude_sum": mag_sum,
        "magnitude_min": mag_min if tiles or voxels else None,
        "magnitude_max": mag_max if tiles or voxels else None,
    }))


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "write":
        write(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "dump":
        dump(sys.argv[2], sys.argv[3])
    else:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
