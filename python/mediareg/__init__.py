"""mediareg from Python: Mitsuba 3 scene files rendered into numpy arrays.

    import mediareg
    scene = mediareg.load_file("mitsuba_scenes/cbox.xml")
    image = mediareg.render(scene, spp=64)        # float32 (H, W, 3), linear RGB
    mediareg.write_exr("cbox.exr", image, spp=64)

The functions are the library's, the ones the ``mediareg`` command line runs: the same
scene, spp and seed give the same image, bit for bit. See docs/python.md.
"""

import warnings as _warnings

import numpy as _np

from . import _mediareg
from ._mediareg import Error, Scene, SceneError

__all__ = [
    "Error",
    "Scene",
    "SceneError",
    "backward",
    "denoise",
    "fit",
    "load_file",
    "merge",
    "read_exr",
    "regularize",
    "render",
    "write_exr",
    "write_vol",
]


def load_file(path, search_path=None, strict_v3=False, sensor=None, **params):
    """Loads a Mitsuba 3 scene file (Mitsuba's ``mi.load_file``).

    ``params`` set the scene's parameters (``$name``), as ``-D name=value`` does: they
    override ``<default>``, and one the scene never uses is an error. ``search_path``:
    folders searched for meshes and includes after the scene's own (the CLI's ``-a``).
    ``strict_v3``: refuse the Mitsuba 0.6 readings (the CLI's ``--strict-v3``).
    ``sensor``: which of the file's sensors the scene is built for (the CLI's ``--sensor``;
    None: the first, with a warning where there are several).

    Raises SceneError with the CLI's ``file:line:col: message``. The loader's warnings
    are issued as Python warnings (and kept in ``scene.warnings``).
    """
    if isinstance(search_path, (str, bytes)) or hasattr(search_path, "__fspath__"):
        search_path = [search_path]
    scene = _mediareg.load_file(
        str(path),
        search_path=None if search_path is None else [str(p) for p in search_path],
        strict_v3=strict_v3,
        sensor=sensor,
        **params,
    )
    for w in scene.warnings:
        _warnings.warn(w, stacklevel=2)
    return scene


def render(scene, spp=None, seed=0, sensor=None, threads=None, gradient=None, medium=None,
           denoise=None):
    """Renders ``scene`` (Mitsuba's ``mi.render``): a float32 array (H, W, 3).

    ``spp``: samples per pixel (None: the sampler's sample_count); ``seed``: as Mitsuba,
    the seed given (0 by default), not the sampler's; ``sensor``: the one the scene was
    loaded for (``load_file(..., sensor=N)``; None: that one); ``threads``: render threads (None: all cores); the image is the same at any
    count. ``gradient="albedo"`` also estimates d(radiance_c)/d(albedo_c) of one medium
    (``medium``: its XML id, needed when the scene has several) in the same paths, and
    returns ``(image, dalbedo)``; a list of parameter names,
    ``gradient=["sigma_t", "albedo", "g", "scale"]``, returns ``(image, {name: d/dname})``
    (signed float32 arrays, per colour channel; sigma_t of a homogeneous medium only,
    scale of any). ``denoise="oidn"`` returns the image through Intel Open
    Image Denoise, as ``mediareg render --denoise oidn`` writes it (the directly seen
    emission kept out, albedo and normal buffers; the library: ``scripts/fetch_oidn`` or
    ``MEDIAREG_OIDN``). The GIL is released; Ctrl-C stops the render and raises
    KeyboardInterrupt.
    """
    return _mediareg.render(
        scene,
        spp=spp,
        seed=seed,
        sensor=sensor,
        threads=threads,
        gradient=gradient,
        medium=medium,
        denoise=denoise,
    )


def denoise(color, albedo=None, normal=None, clean_aux=True):
    """Intel Open Image Denoise's ``RT`` filter on float32 (H, W, 3) arrays: ``color``
    linear HDR radiance (finite, non-negative), optionally the ``albedo`` (in [0, 1])
    and, with it, the ``normal`` of what each pixel sees first; ``clean_aux``: those
    are free of noise. Returns the denoised colour (the same for the same input).
    """
    return _mediareg.denoise(
        _np.ascontiguousarray(color, dtype=_np.float32),
        albedo=None if albedo is None else _np.ascontiguousarray(albedo, dtype=_np.float32),
        normal=None if normal is None else _np.ascontiguousarray(normal, dtype=_np.float32),
        clean_aux=clean_aux,
    )


def regularize(scene, spp=None, seed=0, threads=None, medium=None, predict="difference",
               factor=None, pilot_renders=8, pilot_spp=1, c_beta=0.5, fit_spp=4, fit_at=1.0,
               frames=11, wa=0.1, reproject="exact", orbit=None, target=None, dolly=None,
               camera_path=None, spatial=None, denoise=None, pick=True, oidn_check=False):
    """The paper's method, as ``mediareg regularize`` with the same options (keywords
    named after its flags; ``factor``: a number or "auto", None the CLI's default;
    ``c_beta``: a number or "fit"; ``target``: the orbit's centre (x, y, z); ``spatial``:
    True/False, None the predictor's default; ``predict``: also "plain", the control;
    ``denoise``: "oidn" or "bilateral", None the CLI's default: oidn when the library is
    there; ``pick``: False as ``--no-pick``; ``oidn_check``: True as ``--oidn-check``).
    Returns a dict of float32 (H, W, 3)
    arrays ``predicted``, ``source``, ``dalbedo_raw``, ``dalbedo`` (the CLI's OUT.exr,
    OUT_source.exr, OUT_dalbedo_raw.exr, OUT_dalbedo.exr) and ``albedo_source``,
    ``albedo_target``, ``factor`` (the pilot's, per channel, or None), ``c_beta``,
    ``frames``. The GIL is released; Ctrl-C is seen only when it returns."""
    return _mediareg.regularize(
        scene, spp=spp, seed=seed, threads=threads, medium=medium, predict=predict,
        factor=factor, pilot_renders=pilot_renders, pilot_spp=pilot_spp, c_beta=c_beta,
        fit_spp=fit_spp, fit_at=fit_at, frames=frames, wa=wa, reproject=reproject,
        orbit=orbit, target=None if target is None else tuple(target), dolly=dolly,
        camera_path=None if camera_path is None else str(camera_path), spatial=spatial,
        denoise=denoise, pick=pick, oidn_check=oidn_check,
    )


def fit(path, targets, params=("sigma_t", "albedo", "g"), medium=None, spp=32,
        iterations=None, seed=0, search_path=None, **defines):
    """Fits a medium's parameters to target images (``mediareg fit``).

    ``path``: the scene file (its camera and lighting render the targets; the fit starts
    from its medium's values); ``targets``: float32 arrays (H, W, 3), or ``(array,
    {name: value})`` for a target rendered with other scene parameters (another light);
    ``params``: of sigma_t, albedo, g, scale; ``medium``: the medium's XML id (needed
    when there are several); ``spp``: samples per pixel of each iteration's renders;
    ``iterations``: a fixed count (default: 100, growing up to 400 while the estimate
    still moves);
    ``defines``: scene parameters for every target. Returns a dict: ``params`` (name:
    value; a chromatic one per channel, ``sigma_t[0]``...), ``ci`` (name: (lo, hi), 95%,
    infinite where the images do not determine it), ``loss`` (per iteration),
    ``iterations``, ``converged``, ``seconds``. Ctrl-C raises KeyboardInterrupt.
    """
    targets = [
        (_np.ascontiguousarray(t[0], _np.float32), t[1]) if isinstance(t, tuple)
        else _np.ascontiguousarray(t, _np.float32)
        for t in targets
    ]
    return _mediareg.fit(path, targets, params=list(params), medium=medium, spp=spp,
                         iterations=iterations, seed=seed, search_path=search_path,
                         **defines)


def backward(scene, adjoint, params=("sigma_t",), medium=None, spp=None, seed=0,
             threads=None):
    """Reverse-mode gradients (``mediareg backward``): for an adjoint image ``adjoint``
    (H, W, 3), dL/d(pixel, channel), the gradient of L = sum(adjoint * image) in every
    value of a grid medium's volumes. ``params``: of ``sigma_t`` (its values before the
    medium's scale) and ``albedo``. Returns a dict of float32 arrays shaped as the grids'
    data, (z, y, x) or (z, y, x, 3). A loop of one's own (numpy, PyTorch) writes its
    estimate with ``write_vol`` and loads the scene with it (``load_file(path,
    sigma_t_file=...)`` where the scene names its grid by a parameter): docs/python.md.
    """
    adjoint = _np.ascontiguousarray(adjoint, dtype=_np.float32)
    return _mediareg.backward(scene, adjoint, params=list(params), medium=medium, spp=spp,
                              seed=seed, threads=threads)


def write_vol(path, array):
    """Writes a (z, y, x) or (z, y, x, 3) array as a Mitsuba ``.vol`` grid (bounding box
    the unit cube; the scene's ``to_world`` places it), readable by Mitsuba 3 and mediareg."""
    _mediareg.write_vol(str(path), _np.ascontiguousarray(array, dtype=_np.float32))


def write_exr(path, array, spp=None):
    """Writes an (H, W, 3) array as a linear float32 RGB EXR, as ``mediareg render``
    writes it (``spp`` in the header when given: ``merge`` weights chunks by it). The
    file is written under a temporary name and renamed: an error leaves no file."""
    array = _np.ascontiguousarray(array, dtype=_np.float32)
    if array.ndim != 3:
        raise ValueError(f"the array's shape is {array.shape}; expected (H, W, 3): RGB")
    _mediareg.write_exr(str(path), array, spp)


def read_exr(path):
    """Reads an EXR's RGB channels: a float32 array (H, W, 3)."""
    return _mediareg.read_exr(str(path))


def merge(paths, out=None):
    """Merges renders of one shot made in chunks (distinct seeds), as ``mediareg merge``:
    weighted by the spp in each file's header. Returns a dict with ``image`` (the mean),
    ``variance`` (of the mean, per pixel and channel; None for one chunk), ``spp`` and
    ``chunks``; with ``out``, also writes OUT.exr and OUT_var.exr."""
    return _mediareg.merge([str(p) for p in paths], None if out is None else str(out))
