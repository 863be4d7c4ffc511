"""rephoto: evaluate 3D reconstructions by virtual rephotography, from Python.

The functions call rephoto's C++ library (the same code as the ``rephoto`` command line) and
release the GIL while they work, so Python threads run them in parallel.

Images are numpy arrays H x W (grey) or H x W x C with C = 1 (grey), 2 (grey + alpha), 3 (RGB)
or 4 (RGBA); dtype uint8 (v / 255), uint16 (v / 65535) or float32 (values in [0, 1], used as
they are). Any strides (slices, transposes) are accepted. Because the library's image type owns
its memory, each input image is brought once, in one parallel pass, into the form the CLI's
image decoder gives: uint8 copied as 8-bit samples (as JPEG and 8-bit PNG are kept), float32
copied, uint16 scaled to float; nothing else is copied. :func:`compare` then runs the very
function ``rephoto compare`` runs for each pair (so values are the CLI's, bit for bit).
Returned images (error maps, renderings) are float32 arrays that take over the library's
buffers without a copy. Each thread that calls :func:`compare` keeps its last working buffers
(converted images, masks) for the next call, as the CLI does from pair to pair: touching fresh
memory costs more than the metrics of a small image.

Errors raise :class:`rephoto.Error` (a ``RuntimeError``) with the one-line message of the CLI;
bad arguments raise :class:`rephoto.UsageError`, which is both a ``rephoto.Error`` and a
``ValueError``.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _rephoto
from ._rephoto import Camera, Error, Model, Scene, UsageError, View

__version__: str = _rephoto.__version__
#: How the extension was built (version, build type, compiler) and the instruction-set path its
#: kernels take ("baseline", "avx2" or "avx512"; REPHOTO_ISA forces one, see docs/determinism.md).
build_info: Dict[str, str] = {
    "version": _rephoto.__version__,
    "build_type": _rephoto._build_type,
    "compiler": _rephoto._compiler,
    "isa": _rephoto._isa,
}

#: Metric names as in the SPEC and the CLI, in the CLI's order.
METRICS: Tuple[str, ...] = tuple(_rephoto.metric_names())

PathLike = Union[str, "os.PathLike[str]"]

__all__ = [
    "Camera", "Error", "METRICS", "Model", "Run", "Scene", "UsageError", "View", "build_info",
    "compare", "error_image", "evaluate", "load_model", "load_run", "read_scene", "split",
]


def compare(photo: np.ndarray, render: np.ndarray, mask: Optional[np.ndarray] = None,
            metrics: Optional[Union[str, Sequence[str]]] = None, *,
            render_mask: Optional[np.ndarray] = None, error_images: bool = False,
            window: int = 9, ssim_mode: str = "gaussian", dark: float = 0.0,
            saturated: float = 1.0, compat: Optional[str] = None,
            background: Sequence[float] = (0.0, 0.0, 0.0), resize: bool = False,
            min_alpha: float = 0.0, lpips_weights: Optional[PathLike] = None,
            lpips_net: str = "alex") -> Dict[str, Any]:
    """Compares a photo with a rendering of the same view, as ``rephoto compare`` does.

    Args:
      photo: the photo, H x W [x C] (see the module docstring for dtypes). Its alpha channel,
        if any, marks valid pixels (alpha 0 = ignore).
      render: the rendering, same H x W. Alpha (2 or 4 channels) is the coverage mask (alpha 0 =
        not covered); without alpha, pure black pixels are not covered (the CLI's rule).
      mask: optional H x W bool/uint8 user mask of the photo (0 = ignore the pixel, e.g. sky),
        like ``--photo-masks``.
      metrics: names ("1-ncc", "cb+cr", "zssd", "dssim", "census", "icid", "psnr", "ssim",
        "lpips"), a comma-separated string or "all" (default: all, which is every metric but
        lpips; with ``compat``: psnr and ssim, plus lpips when LPIPS weights are given).
      render_mask: optional mask of the rendering's size overriding its alpha/black rule
        (``--masks``).
      error_images: also return the per-pixel error images (float32 H x W, NaN = not evaluated).
      window: window side of 1-ncc, zssd, census and completeness (odd, ``--window``).
      ssim_mode: "gaussian" (11x11, sigma 1.5) or "skimage" (7x7 uniform, sample covariance).
      dark, saturated: photo pixels with any channel <= dark or >= saturated (after scaling to
        [0, 1]) are ill-exposed and ignored (``--dark``, ``--saturated``).
      compat: "3dgs" or "nerfstudio": psnr and ssim exactly as graphdeco's metrics.py or
        nerfstudio's ns-eval compute them (every pixel, no masks; ``--compat``), for numbers
        comparable with papers. The photo's alpha is composited over ``background``.
      background: RGB in [0, 1] for ``compat`` (the colour the model was trained with).
      resize: a render (and ``render_mask``) of another size is rescaled to the photo's size
        with the CLI's area filter (``--resize``); validity is decided before rescaling.
        Otherwise the sizes must be equal.
      min_alpha: a rendering pixel counts as covered where its alpha reaches this (in [0, 1];
        ``--min-alpha``, e.g. 0.5 as ``evaluate`` counts a Gaussian splat's soft edge); 0 = any
        alpha above 0. An explicit ``render_mask`` overrides it.
      lpips_weights: folder with the LPIPS weight files under their original names (alex.pth +
        alexnet-owt-7be5be79.pth, or vgg.pth + vgg16-397923af.pth; default:
        $REPHOTO_LPIPS_WEIGHTS), needed when "lpips" is asked (docs/lpips.md). Its value is the
        LPIPS spatial map's mean over the validity mask, or with ``compat`` the whole-image
        value of the lpips package (v0.1, normalize=True) as papers print it; its error image
        is the spatial map. The network is loaded once per process.
      lpips_net: "alex" (the lpips package's default) or "vgg".

    Returns:
      A dict: "completeness" (float, NaN if the photo has no valid window),
      "valid_photo_windows", "valid_both_windows", "resized" (not in compat mode), one float per metric
      (its masked mean; psnr in dB; NaN when nothing was evaluated), "evaluated" (metric ->
      positions in the mean) and, with ``error_images``, "errors" (metric -> array).

    Raises:
      UsageError: bad dtype, shape, sizes, metric name or option.
      Error: anything the library rejects.
    """
    return _rephoto.compare(photo, render, mask, metrics, render_mask, error_images, window,
                            ssim_mode, dark, saturated, compat, list(background), resize,
                            min_alpha, None if lpips_weights is None else os.fspath(lpips_weights),
                            lpips_net)


def error_image(photo: np.ndarray, render: np.ndarray, metric: str,
                mask: Optional[np.ndarray] = None, **options: Any) -> np.ndarray:
    """The per-pixel error image of one metric (float32 H x W; NaN where not evaluated).

    For window metrics the value at (y, x) belongs to the window centred there; psnr's image
    is the squared error averaged over the channels. Options as :func:`compare`.
    """
    result = compare(photo, render, mask, [metric], error_images=True, **options)
    return next(iter(result["errors"].values()))


def read_scene(path: PathLike, format: Optional[str] = None, *,
               image_root: Optional[PathLike] = None, check_image_sizes: bool = True) -> Scene:
    """Reads a scene (COLMAP, transforms.json, cameras.json, Bundler, Middlebury, Strecha, MVE,
    mvs-texturing; detected unless ``format`` names one).

    The result has ``views`` (each with ``name``, ``image_path``, ``camera`` (model name,
    width, height, params in COLMAP order), ``width``, ``height`` and ``cam_from_world``, a
    4x4 float64 matrix: x_cam = R x_world + t, camera looking along +z, y down; pixel (0, 0)'s
    centre at (0.5, 0.5)). ``scene["name"]`` and ``scene[i]`` pick a view.
    """
    return _rephoto.read_scene(os.fspath(path), format,
                               None if image_root is None else os.fspath(image_root),
                               check_image_sizes)


def split(scene: Union[Scene, Iterable[str]], scheme: str = "kfold:5",
          seed: Optional[int] = None) -> Dict[str, Any]:
    """Splits a scene's views (or a list of image names) into training and test sets.

    ``scheme`` as ``rephoto split --scheme``: "kfold:K[:SEED]", "interleaved:K", "loo",
    "every:N", "fraction:F[:SEED]", "lists:TRAIN,TEST", "none". ``seed`` overrides the seed of
    the seeded schemes. Returns {"scheme", "cross_validated", "folds": [{"train", "test"}]},
    names sorted.
    """
    return _rephoto.split(scene, scheme, seed)


def load_model(path: PathLike, *, point_radius: float = 0.0) -> Model:
    """Loads a mesh or point cloud (PLY, OBJ) or 3D Gaussians (3DGS PLY, compressed PLY, .splat).

    ``model.render(view, cam_from_world=None, spp=4, seed=0, backfaces=True,
    background=(0, 0, 0), gaussian_mode="classic")`` renders at a :class:`View` (or a
    :class:`Camera` with an explicit 4x4 ``cam_from_world``) and returns ``(rgba, depth)``:
    float32 H x W x 4 (straight alpha = coverage) and H x W camera-frame z (NaN = empty).
    ``spp`` applies to meshes and point clouds; ``background`` and ``gaussian_mode``
    ("classic" or "antialiased"; anything else raises :class:`UsageError`) to Gaussians.
    The file is resolved, read and rendered as ``rephoto render MODEL`` does (the library's
    renderer factory, ``src/rephoto/representation/make_renderer.h``).
    """
    return _rephoto.load_model(os.fspath(path), point_radius)


@dataclass
class Run:
    """A run folder of ``rephoto evaluate`` (or ``rephoto compare``).

    Attributes:
      path: the folder.
      per_image: rows of per_image.csv as dicts, read by the C++ reader's rule (run/run_table.h,
        the same for ``rephoto report`` and the benchmark service): text columns as str, counts
        (width, height, *_evaluated, ...) as int, measurements (completeness, metrics) as float
        with NaN where nothing was evaluated; columns this version does not know as str.
      per_fold: rows of per_fold.csv likewise (empty for a compare run).
      summary: summary.json.
      run: run.json (empty for a compare run).
    """
    path: str
    per_image: List[Dict[str, Any]] = field(default_factory=list)
    per_fold: List[Dict[str, Any]] = field(default_factory=list)
    summary: Dict[str, Any] = field(default_factory=dict)
    run: Dict[str, Any] = field(default_factory=dict)

    def per_image_frame(self):
        """per_image as a pandas DataFrame (needs pandas)."""
        import pandas
        return pandas.DataFrame(self.per_image)

    def per_fold_frame(self):
        """per_fold as a pandas DataFrame (needs pandas)."""
        import pandas
        return pandas.DataFrame(self.per_fold)


def load_run(path: PathLike) -> Run:
    """Reads a run folder's per_image.csv, per_fold.csv, summary.json and run.json.

    The tables are read by the C++ reader (``rephoto report`` reads them the same way); a
    malformed table raises :class:`Error` naming the file, line and column.
    """
    path = os.fspath(path)
    tables = _rephoto._load_run_tables(path)

    def read_json(name: str) -> Dict[str, Any]:
        file = os.path.join(path, name)
        if not os.path.exists(file):
            return {}
        with open(file) as f:
            return json.load(f)

    return Run(path=path, per_image=tables["per_image"], per_fold=tables["per_fold"],
               summary=read_json("summary.json"), run=read_json("run.json"))


def evaluate(**options: Any) -> Run:
    """Runs ``rephoto evaluate`` with the CLI's settings as keyword arguments and loads the run.

    Names are the flags without "--" ('-' or '_'), e.g. ``scene="data/sceaux", model="m.ply",
    scheme="kfold:5", out="runs/a", metrics=["1-ncc", "psnr"], colorize=True``; ``config=`` reads
    a TOML/JSON config file first (flags override it, as on the command line). See
    ``rephoto evaluate --help`` for every setting. Returns :func:`load_run` of ``out``.

    The numbers papers publish, in one call (as ``rephoto evaluate --compat``):
    ``evaluate(scene=..., model=".../point_cloud/iteration_30000/point_cloud.ply",
    compat="3dgs", out=...)`` splits every:8 (3DGS's llffhold), computes whole-image PSNR/SSIM as
    graphdeco's metrics.py does (``compat="nerfstudio"``: as ns-eval) beside rephoto's masked
    metrics, and writes ``results.json``/``per_view.json`` (``output.json``) into ``out``; the
    run's ``per_image`` rows hold them as ``3dgs_psnr``, ``3dgs_ssim``. ``background=(1, 1, 1)``
    for models trained on white.
    """
    return load_run(_rephoto.evaluate(**options))
