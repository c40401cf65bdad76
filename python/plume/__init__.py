"""plume from Python: render an OpenVDB file or NumPy arrays, get the image back as arrays.

The API mirrors the scene file (docs/scene-file.md): anything a scene file can say, a
:class:`Scene` can say, as nested dicts of the same keys::

    import plume
    scene = plume.Scene(volume={"file": "explosion.vdb"}, medium={"albedo": 0.8},
                        camera={"width": 320, "height": 240}, render={"spp": 16})
    image = plume.render(scene)
    image.beauty            # float32 array (height, width, 4): premultiplied RGBA
    image.stats["spp"]      # the statistics record of `plume render --stats`
    image.write_exr("explosion.exr")

Arrays in::

    volume = plume.Volume.from_numpy(density, temperature=kelvin, voxel_size=0.01)
    image = plume.render(plume.Scene(volume=volume, camera={"width": 256, "height": 256}))

Renders go through the same pipeline as ``plume render``: the same image, bit for bit, as
the command line gives for the same scene. The interpreter is released while rendering;
Ctrl-C stops a render at the end of its current pass and raises ``KeyboardInterrupt``.
Errors are :class:`SceneError` (a bad key or value), :class:`InputError` (a file or array
that cannot be read) and :class:`RenderError`, all :class:`Error`, with the command line's
one-line messages; warnings (clamped voxels, a missing emission grid…) go to the
``logging`` logger ``plume``. As on the command line, VDB files are read in a separate,
resource-limited process (this interpreter, running only the reader), so that a damaged or
hostile file raises :class:`InputError` instead of crashing Python; the scene key
``reading.no_isolation`` reads them in this process.
"""

from __future__ import annotations

import json
import os
import sys
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np

from . import _plume
from ._plume import Error, InputError, RenderError, SceneError

__all__ = [
    "Error",
    "InputError",
    "Render",
    "RenderError",
    "Scene",
    "SceneError",
    "Volume",
    "info",
    "read_exr",
    "render",
    "write_vdb",
]

PathLike = Union[str, "os.PathLike[str]"]

# The isolated VDB reader: this interpreter, without site packages, loading only the
# extension module from its directory and serving the reader's arguments
_READER_CODE = "import sys; sys.path.insert(0, sys.argv.pop(1)); import _plume; _plume.reader_main(sys.argv[1:])"
if os.path.basename(sys.executable or "").lower().startswith("python"):
    _plume.use_isolated_reader(sys.executable, ["-S", "-c", _READER_CODE, os.path.dirname(_plume.__file__)])
# else an application embedding Python, whose executable may not take -S -c: files are
# read in this process, as with reading.no_isolation

#: The volume file a scene built around arrays names until it is rendered.
_ARRAYS_PLACEHOLDER = "<numpy arrays>.vdb"


def _world_from_index(voxel_size: Any, origin: Any, transform: Any) -> List[List[float]]:
    """Three rows of the affine index-to-world map: `transform` (4×4), or a scale by
    `voxel_size` (a number or three) with voxel (0, 0, 0) centred at `origin`."""
    if transform is not None:
        m = np.asarray(transform, dtype=np.float64)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise InputError(f"transform: a finite 4x4 matrix is needed, got shape {m.shape}")
        if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
            raise InputError(f"transform: the last row must be [0, 0, 0, 1] (affine), got {m[3].tolist()}")
        return m[:3].tolist()
    size = np.broadcast_to(np.asarray(voxel_size, dtype=np.float64), (3,))
    if not np.all(np.isfinite(size)) or np.any(size <= 0):
        raise InputError(f"voxel_size: must be positive and finite, got {np.asarray(voxel_size).tolist()}")
    o = np.asarray(origin, dtype=np.float64)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise InputError(f"origin: three finite numbers are needed, got {np.asarray(origin).tolist()}")
    return [
        [size[0], 0.0, 0.0, o[0]],
        [0.0, size[1], 0.0, o[1]],
        [0.0, 0.0, size[2], o[2]],
    ]


def _float32(name: str, array: Any, shape: Optional[Sequence[int]], vector: bool = False) -> np.ndarray:
    """`array` as float32 (float64 converted), checked for dimensions and shape."""
    a = np.asarray(array)
    if a.dtype not in (np.float32, np.float64):
        raise InputError(f"grid {name!r}: dtype {a.dtype}; give float32 or float64 values")
    want = 4 if vector else 3
    if a.ndim != want or (vector and a.shape[3] != 3):
        form = "(nx, ny, nz, 3)" if vector else "(nx, ny, nz)"
        raise InputError(f"grid {name!r}: shape {a.shape}; a {'vector ' if vector else ''}grid is {form}")
    if shape is not None and tuple(a.shape[:3]) != tuple(shape):
        raise InputError(f"grid {name!r}: shape {a.shape[:3]} differs from the density's {tuple(shape)}")
    return a.astype(np.float32, copy=False)


class Volume:
    """Grids made from dense NumPy arrays, held as the sparse 8³ leaves a VDB file holds.

    Element ``a[i, j, k]`` is voxel ``(i, j, k)`` (x, y, z) of the grid's index space; a
    leaf of 8³ voxels that all equal the background is not stored. Use
    :meth:`from_numpy` to make one, :class:`Scene` (``volume=``) to render it, and
    :meth:`write_vdb` to write it for other tools.
    """

    def __init__(self, data: "_plume.VolumeData") -> None:
        self._data = data

    @classmethod
    def from_numpy(
        cls,
        density: Any,
        temperature: Any = None,
        emission: Any = None,
        velocity: Any = None,
        *,
        voxel_size: Union[float, Sequence[float]] = 1.0,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        transform: Any = None,
        background: float = 0.0,
        grids: Optional[Mapping[str, Any]] = None,
    ) -> "Volume":
        """Grids from dense arrays of shape ``(nx, ny, nz)``, float32 or float64.

        - ``density``: the density grid ``density``; ``temperature`` (Kelvin, the
          ``temperature`` grid), ``emission`` (the ``emission`` grid), ``velocity``
          (``(nx, ny, nz, 3)``, world units per second, the vector grid ``velocity``);
          ``grids``: more float grids by name (an albedo grid, say).
        - Placement: ``voxel_size`` (a number, or three) with voxel (0, 0, 0) centred at
          ``origin``, or a 4×4 affine ``transform`` from index to world space.
        - ``background``: the value outside the stored leaves (of the float grids).

        Arrays of any memory order and strides are accepted; float64 is converted to
        float32 (what a VDB file holds) and each array is copied once while its leaves are
        built. NaN or infinite values, a shape other than the density's, other dtypes or
        dimensions raise :class:`InputError`.
        """
        rows = _world_from_index(voxel_size, origin, transform)
        data = _plume.VolumeData(rows, float(background))
        d = _float32("density", density, None)
        data.add_grid("density", d)
        named = {"temperature": temperature, "emission": emission, **dict(grids or {})}
        for name, array in named.items():
            if array is not None:
                data.add_grid(name, _float32(name, array, d.shape))
        if velocity is not None:
            v = _float32("velocity", velocity, d.shape, vector=True)
            data.add_vector("velocity", v[..., 0], v[..., 1], v[..., 2])
        return cls(data)

    @property
    def grid_names(self) -> List[str]:
        """The float grids held, by name."""
        return list(self._data.grid_names)

    @property
    def leaf_counts(self) -> Dict[str, int]:
        """Leaves (8³ voxels each) stored per float grid."""
        return dict(self._data.leaf_counts)

    def write_vdb(self, path: PathLike) -> None:
        """Write the grids to the OpenVDB file ``path`` (float grids, and the velocity as
        a vector grid), atomically."""
        self._data.write(os.fspath(path))


def write_vdb(
    path: PathLike,
    grids: Mapping[str, Any],
    *,
    voxel_size: Union[float, Sequence[float]] = 1.0,
    origin: Sequence[float] = (0.0, 0.0, 0.0),
    transform: Any = None,
    background: float = 0.0,
) -> None:
    """Write dense arrays as an OpenVDB file: ``grids`` maps names to ``(nx, ny, nz)``
    float arrays (float grids) or ``(nx, ny, nz, 3)`` arrays (vector grids), placed as in
    :meth:`Volume.from_numpy`."""
    data = _plume.VolumeData(_world_from_index(voxel_size, origin, transform), float(background))
    shape = None
    for name, array in grids.items():
        a = np.asarray(array)
        if a.ndim == 4:
            v = _float32(name, a, shape, vector=True)
            data.add_vector(name, v[..., 0], v[..., 1], v[..., 2])
        else:
            g = _float32(name, a, shape)
            data.add_grid(name, g)
        shape = a.shape[:3]
    data.write(os.fspath(path))


class Scene:
    """A scene and its job settings, as a scene file holds them.

    ``Scene(**tables)`` takes the scene file's tables as keyword arguments, each a dict of
    its keys (nested dicts for nested tables; lists for arrays)::

        Scene(volume={"file": "smoke.vdb", "density_grid": "density"},
              medium={"albedo": 0.8, "density_scale": 4.0},
              camera={"width": 320, "height": 240, "fov": 35.0},
              render={"spp": 64, "seed": 1})

    ``volume`` may also be a :class:`Volume` (its grids bound as ``density``,
    ``temperature``, ``emission``), or a dict whose ``file`` is one. Keys and defaults are
    the scene file's (docs/scene-file.md); relative paths are relative to the working
    directory. A bad key or value raises :class:`SceneError` naming it.
    """

    def __init__(self, volume: Union[None, Volume, Mapping[str, Any]] = None, **tables: Any) -> None:
        self._arrays: Optional[Volume] = None
        keys: Dict[str, Any] = dict(tables)
        if isinstance(volume, Volume):
            self._arrays, volume = volume, {}
        elif volume is not None and isinstance(volume.get("file"), Volume):
            volume = dict(volume)
            self._arrays = volume.pop("file")
        if volume is not None:
            keys["volume"] = dict(volume)
        if self._arrays is not None:
            keys["volume"] = {**keys.get("volume", {}), "file": _ARRAYS_PLACEHOLDER}
        self._shot = _plume.Shot.from_keys(keys, os.getcwd())

    @classmethod
    def from_toml(cls, path: PathLike) -> "Scene":
        """Read a scene file; its relative paths are relative to the file's directory."""
        scene = cls.__new__(cls)
        scene._arrays = None
        scene._shot = _plume.Shot.from_toml(os.fspath(path))
        return scene

    def to_toml(self) -> str:
        """The scene as a scene file, every path absolute: ``plume render`` renders it as
        :func:`render` does. A scene around a :class:`Volume` has no file to name: write
        the volume with :meth:`Volume.write_vdb` and name that file instead."""
        if self._arrays is not None:
            raise SceneError(
                "volume.file: this scene renders NumPy arrays, which a scene file cannot hold; "
                "write them with Volume.write_vdb(path) and build the scene with volume={'file': path}"
            )
        return self._shot.to_toml(os.getcwd())

    def write_toml(self, path: PathLike) -> None:
        """Write :meth:`to_toml` to ``path``."""
        text = self.to_toml()
        with open(os.fspath(path), "w", encoding="utf-8") as f:
            f.write(text)

    def __repr__(self) -> str:
        what = "NumPy arrays" if self._arrays is not None else repr(os.fspath(self._shot.volume_file))
        return f"plume.Scene(volume={what})"


class Render:
    """A rendered frame.

    - ``beauty``: float32 array ``(height, width, 4)``, premultiplied RGBA, rows from the
      top, as in the EXR's data window (the crop, if one was asked for);
    - ``layers``: the AOV layers by name (``emission``, ``scattered``, …), float32 arrays
      ``(height, width, channels)``, their channel names in ``layer_channels``;
    - ``stats``: the statistics record, as ``plume render --stats`` writes it.
    """

    def __init__(self, data: "_plume.RenderData") -> None:
        self._data = data
        h, w = data.height, data.width

        def channel(name: str) -> np.ndarray:
            return np.frombuffer(data.channel(name), dtype="<f4").reshape(h, w)

        names = list(data.channel_names)
        rgba = ["R", "G", "B", "A"]
        self.beauty: np.ndarray = np.stack([channel(c) for c in rgba], axis=-1)
        groups: Dict[str, List[str]] = {}
        # EXR stores channels sorted by name; a layer's come back as R, G, B, A, X, Y, Z,
        # then the others by name
        usual = {c: i for i, c in enumerate("RGBAXYZ")}
        names.sort(key=lambda n: (n.rsplit(".", 1)[0], usual.get(n.rsplit(".", 1)[-1], 99), n))
        for n in names:
            if n in rgba:
                continue
            layer = n.rsplit(".", 1)[0] if "." in n else n
            groups.setdefault(layer, []).append(n)
        self.layers: Dict[str, np.ndarray] = {
            layer: np.stack([channel(c) for c in chans], axis=-1)
            for layer, chans in groups.items()
        }
        self.layer_channels: Dict[str, List[str]] = {
            layer: [c.rsplit(".", 1)[-1] for c in chans] for layer, chans in groups.items()
        }
        self.stats: Dict[str, Any] = json.loads(data.stats_json)

    @property
    def width(self) -> int:
        """Width of the image (its data window)."""
        return int(self._data.width)

    @property
    def height(self) -> int:
        """Height of the image (its data window)."""
        return int(self._data.height)

    def write_exr(self, path: PathLike) -> None:
        """Write the frame as the EXR file ``plume render`` writes (its layers and its
        header: the statistics record and the scene), atomically."""
        self._data.write_exr(os.fspath(path))

    def write_png(self, path: PathLike, exposure: Optional[float] = None) -> None:
        """Write the beauty as an 8-bit sRGB PNG, as ``plume render``'s preview:
        brightened by ``exposure`` stops, or exposed automatically when None."""
        self._data.write_png(os.fspath(path), exposure)

    def __repr__(self) -> str:
        return f"plume.Render({self.width}x{self.height}, {self.stats.get('spp')} spp, layers {sorted(self.layers)})"


def render(scene: Scene, progress: Optional[Callable[[Dict[str, Any]], Any]] = None) -> Render:
    """Render ``scene`` and return the frame (:class:`Render`).

    ``progress``, if given, is called after each pass with a dict: ``done`` and ``target``
    (samples per pixel; ``target`` is 0 under a time budget), ``resumed``, ``fraction``
    (0 … 1) and ``frame``. An exception it raises stops the render after that pass and is
    raised here. The interpreter is released while rendering, so other Python threads run
    (and may render too); Ctrl-C stops the render at the end of its current pass and
    raises ``KeyboardInterrupt``. With ``farm.time_limit`` the frame reached when it runs
    out is returned, ``stats["status"]`` saying ``"time-limit"``. The scene renders one
    frame: its output paths are not written (use :meth:`Render.write_exr`).

    Raises :class:`SceneError`, :class:`InputError` or :class:`RenderError` with the
    command line's one-line message.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"render() takes a plume.Scene, not {type(scene).__name__}")
    arrays = scene._arrays._data if scene._arrays is not None else None
    data = _plume.render_shot(scene._shot, os.getcwd(), arrays, progress)
    return Render(data)


def read_exr(path: PathLike) -> Render:
    """Read an EXR file (one ``plume render`` wrote, say) as a :class:`Render`: its
    beauty and layers; ``stats`` is empty."""
    return Render(_plume.read_exr(os.fspath(path)))


def info(path: PathLike) -> Union[List[Dict[str, Any]], Dict[str, Any]]:
    """What ``plume info --json`` prints: for a ``.vdb`` file a list with one dict per
    grid (``name``, ``type``, ``active_voxels``, ``index_bbox``, ``voxel_size``,
    ``transform``, ``min``, ``max``, …); for a ``.plume`` brick cache, after checking its
    checksums, a dict of its contents."""
    return json.loads(_plume.info_json(os.fspath(path)))
