"""A review page for a result in the browser: the GLB played with three.js, and a local server.

:func:`write_review_page` writes one self-contained HTML file: the vendored three.js r187
modules (``facecap/data/three``, MIT) inlined as ES modules, the page's own script
(``facecap/data/review``) and, when small enough, the GLB itself. It plays the GLB's weights
animation, shows its ``marker:<label>`` nodes as spheres and, given per-vertex error, a heat
map with a colour bar. :func:`serve` is the tiny localhost server ``facecap view`` runs for a
page whose GLB lies beside it (a ``file://`` page cannot read a neighbouring file).
"""

from __future__ import annotations

import base64
import functools
import html as html_lib
import json
import math
import os
import re
import struct
import threading
import urllib.parse
from collections.abc import Sequence
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps

from .. import __version__
from ..errors import FileFormatError, InputError
from ..io.atomic_write import atomic_path

__all__ = ["write_review_page", "serve", "ReviewServer", "EMBED_LIMIT_BYTES"]

EMBED_LIMIT_BYTES = 60_000_000
"""Largest GLB embedded in the page by default (bytes). Base64 makes it 4/3 larger in the
HTML (80 MB at the limit), which Chromium and Firefox open in a few seconds; a larger GLB is
linked instead, and the page then needs :func:`serve` (``facecap view``)."""

ERROR_CMAP = "inferno"
"""Colour map of the error heat map: the one :func:`facecap.report.render_mesh` uses for error."""

_NO_VALUE = 255
"""Quantised error level meaning 'no value' (NaN), drawn grey; levels 0-254 span the range."""
_NO_VALUE_GREY = (0.62, 0.62, 0.62)
_BACKGROUND = "#33373d"
_DATA = Path(__file__).resolve().parent.parent / "data"
_THREE_REVISION = "187"

# Specifier -> (vendored file, rewrites of its relative imports into the page's bare specifiers).
# Modules behind blob: URLs cannot resolve './x.js', so every relative import is rewritten; a
# vendored update that adds one fails loudly in _module_sources.
_MODULES: dict[str, tuple[str, tuple[tuple[str, str], ...]]] = {
    "three/build/three.core.js": ("three.core.js", ()),
    "three": ("three.module.js", (("'./three.core.js'", "'three/build/three.core.js'"),)),
    "three/addons/utils/BufferGeometryUtils.js": ("BufferGeometryUtils.js", ()),
    "three/addons/utils/SkeletonUtils.js": ("SkeletonUtils.js", ()),
    "three/addons/loaders/GLTFLoader.js": (
        "GLTFLoader.js",
        (
            ("'../utils/BufferGeometryUtils.js'", "'three/addons/utils/BufferGeometryUtils.js'"),
            ("'../utils/SkeletonUtils.js'", "'three/addons/utils/SkeletonUtils.js'"),
        ),
    ),
    "three/addons/controls/OrbitControls.js": ("OrbitControls.js", ()),
    # For GLBs written with EXT_meshopt_compression (facecap.io.write_gltf(compress=True)).
    "three/addons/libs/meshopt_decoder.module.js": ("meshopt_decoder.module.js", ()),
}
_RELATIVE_IMPORT = re.compile(r"""(?:from|import)\s*\(?\s*['"]\.{1,2}/""")


@functools.lru_cache(maxsize=1)
def _module_sources() -> tuple[tuple[str, str], ...]:
    """The vendored three.js modules with their imports rewritten, as (specifier, source)."""
    out = []
    for specifier, (file_name, rewrites) in _MODULES.items():
        path = _DATA / "three" / file_name
        try:
            source = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise FileFormatError(f"vendored three.js file missing from the installation ({exc})",
                                  path=str(path)) from None
        for old, new in rewrites:
            if old not in source:
                raise FileFormatError(f"expected the import {old} in the vendored file", path=str(path))
            source = source.replace(old, new)
        if _RELATIVE_IMPORT.search(source):
            raise FileFormatError("vendored module still has a relative import the page cannot resolve",
                                  path=str(path))
        out.append((specifier, _script_safe(source, path)))
    return tuple(out)


def _script_safe(source: str, path: Path) -> str:
    """Check text can sit raw inside a <script> element (no '</script' nor '<!--' to end or escape it)."""
    lowered = source.lower()
    if "</script" in lowered or "<!--" in lowered:
        raise FileFormatError("holds '</script' or '<!--' and cannot be inlined in a page", path=str(path))
    return source


def _json_for_script(value: Any) -> str:
    """JSON that can sit inside a <script> element: '</' and '<!--' escaped (still valid JSON)."""
    return json.dumps(value, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


def _glb_summary(glb_path: Path) -> dict[str, Any]:
    """Read a GLB's JSON chunk (not its binary one): the face mesh's vertex count and marker names."""
    try:
        with open(glb_path, "rb") as handle:
            header = handle.read(20)
            if len(header) < 20:
                raise FileFormatError("is not a GLB file (shorter than its 20-byte header)", path=str(glb_path))
            magic, version, _length, chunk_length, chunk_type = struct.unpack("<4sIIII", header)
            if magic != b"glTF" or version != 2 or chunk_type != 0x4E4F534A:
                raise FileFormatError("is not a glTF 2.0 binary (GLB) file", path=str(glb_path))
            doc = json.loads(handle.read(chunk_length))
    except OSError as exc:
        raise InputError(f"cannot read the GLB ({exc.strerror or exc})", path=str(glb_path)) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"unreadable glTF JSON chunk ({exc})", path=str(glb_path)) from None
    meshes = doc.get("meshes") or []
    accessors = doc.get("accessors") or []
    if not meshes:
        raise FileFormatError("the GLB holds no mesh", path=str(glb_path))

    def vertex_count(mesh: dict[str, Any]) -> int:
        try:
            return int(accessors[mesh["primitives"][0]["attributes"]["POSITION"]]["count"])
        except (KeyError, IndexError, TypeError, ValueError):
            raise FileFormatError("a mesh has no readable POSITION accessor", path=str(glb_path)) from None

    # The same choice as the page's: the mesh with morph targets, else the one with most vertices.
    face = max(meshes, key=lambda m: (bool(m.get("primitives", [{}])[0].get("targets")), vertex_count(m)))
    nodes = doc.get("nodes") or []
    markers = [str(n.get("name", ""))[len("marker:"):] for n in nodes if str(n.get("name", "")).startswith("marker:")]
    for group in nodes:  # facecap.io.write_gltf: the children of a node named "Markers"
        if group.get("name") == "Markers":
            markers += [str(nodes[c].get("name", "")) for c in group.get("children") or [] if 0 <= c < len(nodes)]
    return {"n_vertices": vertex_count(face), "marker_labels": markers,
            "n_animations": len(doc.get("animations") or [])}


def _error_levels(
    error: Any, n_vertices: int, n_frames: int, error_frames: Any, error_range_mm: Any
) -> tuple[np.ndarray, list[int], tuple[float, float]]:
    """Quantise per-vertex error (mm) to uint8 levels 0-254 over the range, 255 for NaN."""
    try:
        E = np.asarray(error, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("error: expected a numeric (n,) or (S, n) array, mm") from None
    if E.ndim == 1:
        E = E[None]
    if E.ndim != 2 or E.shape[1] != n_vertices or E.shape[0] < 1:
        raise InputError(f"error: expected shape ({n_vertices},) or (S, {n_vertices}) (one value per vertex "
                         f"of the GLB's mesh), got {np.shape(error)}")
    if np.any(np.isinf(E)):
        raise InputError("error: contains infinite values (use NaN for 'no value')")
    S = E.shape[0]
    if error_frames is None:
        frames = np.round(np.linspace(0, n_frames - 1, S)).astype(np.int64) if S > 1 else np.zeros(1, np.int64)
    else:
        frames = np.asarray(error_frames)
        if frames.shape != (S,) or not np.issubdtype(frames.dtype, np.integer):
            raise InputError(f"error_frames: expected {S} integer frame indices, got {np.shape(error_frames)}")
        frames = frames.astype(np.int64)
    if (S > 1 and frames[0] != 0) or np.any(np.diff(frames) <= 0) or frames.min() < 0 or frames.max() >= n_frames:
        raise InputError(f"error_frames: expected increasing frames in [0, {n_frames}) starting at 0, "
                         f"got {frames.tolist()[:8]}")
    if S == 1:
        frames = np.zeros(1, np.int64)
    finite = E[np.isfinite(E)]
    if error_range_mm is None:
        lo, hi = 0.0, float(finite.max()) if finite.size else 1.0
    else:
        try:
            lo, hi = (float(x) for x in error_range_mm)
        except (TypeError, ValueError):
            raise InputError(f"error_range_mm: expected (low, high) in mm, got {error_range_mm!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise InputError(f"error_range_mm: expected finite low < high, got {error_range_mm!r}")
    if hi <= lo:
        hi = lo + 1.0  # a constant error: any range shows it
    levels = np.full(E.shape, _NO_VALUE, dtype=np.uint8)
    ok = np.isfinite(E)
    levels[ok] = np.round(np.clip((E[ok] - lo) / (hi - lo), 0.0, 1.0) * (_NO_VALUE - 1)).astype(np.uint8)
    return levels, frames.tolist(), (lo, hi)


def _through_vertex_source(error: Any, vertex_source: Any, n_written: int) -> np.ndarray:
    """Error per GLB vertex from error per mesh vertex (write_gltf copies mesh vertices along UV seams)."""
    source = np.asarray(vertex_source)
    if source.shape != (n_written,) or not np.issubdtype(source.dtype, np.integer):
        raise InputError(f"vertex_source: expected {n_written} integer indices (one per GLB vertex), "
                         f"got shape {source.shape}, dtype {source.dtype}")
    try:
        E = np.asarray(error, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("error: expected a numeric (n,) or (S, n) array, mm") from None
    if E.ndim not in (1, 2) or (source.size and (source.min() < 0 or source.max() >= E.shape[-1])):
        raise InputError(f"vertex_source: indices must lie in [0, {E.shape[-1] if E.ndim else 0}), the error's "
                         f"vertex count, got [{source.min()}, {source.max()}]")
    return E[..., source]


def _error_lut() -> list[list[float]]:
    """255 colours of the error map (sRGB, 0-1) for levels 0-254, then the no-value grey."""
    rgb = colormaps[ERROR_CMAP](np.linspace(0.0, 1.0, _NO_VALUE))[:, :3]
    return [[round(float(c), 4) for c in row] for row in rgb] + [list(_NO_VALUE_GREY)]


def write_review_page(
    out_html: str | os.PathLike[str],
    glb_path: str | os.PathLike[str],
    *,
    title: str,
    rate: float,
    n_frames: int,
    marker_labels: Sequence[str] | None = None,
    error: Any = None,
    error_frames: Any = None,
    error_range_mm: tuple[float, float] | None = None,
    vertex_source: Any = None,
    embed: bool | None = None,
) -> Path:
    """Write a self-contained HTML page that plays a facecap GLB in the browser (three.js).

    Parameters
    ----------
    out_html : str or path-like
        Page to write (atomically: a temporary sibling renamed on success).
    glb_path : str or path-like
        The result's GLB: one mesh with morph targets and a weights animation, and optionally
        nodes named ``marker:<label>`` with a translation animation.
    title : str
        Page title and heading.
    rate : float
        Frame rate of the take, Hz (frame ``i`` is at ``i / rate`` seconds in the GLB's animation).
    n_frames : int
        Number of frames; the scrubber runs over ``0 .. n_frames - 1``.
    marker_labels : sequence of str or None, optional
        The markers the GLB must carry as ``marker:<label>`` nodes, checked against the file;
        default None takes whatever marker nodes it has.
    error : (n,) or (S, n) float array, mm, or None, optional
        Per-vertex error on the GLB's mesh (``n`` = its vertex count, in the file's vertex
        order): one value per vertex for the whole take, or ``S`` rows sampled at
        ``error_frames``, each shown from its frame until the next row's. NaN is 'no value'
        (grey). Stored in the page quantised to 255 levels over ``error_range_mm``.
    error_frames : (S,) int array or None, optional
        The frame of each error row, increasing, starting at 0; default ``S`` frames evenly
        spread over the take (``round(linspace(0, n_frames - 1, S))``).
    error_range_mm : (float, float) or None, optional
        Error mapped to the ends of the colour bar, mm; default ``(0, max error)``.
    vertex_source : (n_written,) int array or None, optional
        When ``error`` is given on the mesh that was written rather than on the GLB's vertices:
        the mesh vertex each GLB vertex copies (``write_gltf``'s ``vertex_source``, which
        splits vertices along UV seams); the error is then ``error[..., vertex_source]``.
    embed : bool or None, optional
        Put the GLB inside the page (base64), so the page opens from ``file://`` with nothing
        beside it. Default None embeds a GLB of at most :data:`EMBED_LIMIT_BYTES` (60 MB) and
        links a larger one by its path relative to the page (open it with :func:`serve`).

    Returns
    -------
    pathlib.Path
        ``out_html``.

    Raises
    ------
    InputError
        If the GLB is missing or not glTF 2.0 binary, the marker labels or error do not match
        it, or an option is out of range.

    Notes
    -----
    The page loads nothing from the network: three.js (r187, MIT, ``facecap/data/three``) is
    inlined and served to itself through blob URLs and an import map. It exposes
    ``window.facecapReview`` (``ready``, ``nFrames``, ``setFrame(i)``, ``frame()``, ``play()``,
    ``pause()``, ``setMarkersVisible(b)``, ``setErrorVisible(b)``, ``setCamera({left, right,
    bottom, top})``: an orthographic front view of that world window, as
    :func:`~facecap.report.render_mesh`'s ``'front'``, and ``resetCamera()``) for tests and scripts.
    Error data costs ``S * n`` bytes (4/3 of that in the page): 100 rows at 700k vertices are 93 MB.
    """
    glb = Path(glb_path)
    if not glb.is_file():
        raise InputError("GLB not found", path=str(glb))
    if not isinstance(title, str):
        raise InputError(f"title: expected a str, got {type(title).__name__}")
    try:
        rate_hz = float(rate)
    except (TypeError, ValueError):
        raise InputError(f"rate: expected a frame rate in Hz, got {rate!r}") from None
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"rate: expected a positive frame rate in Hz, got {rate!r}")
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise InputError(f"n_frames: expected a positive integer, got {n_frames!r}")
    n_frames = int(n_frames)
    summary = _glb_summary(glb)
    labels = summary["marker_labels"]
    if marker_labels is not None:
        wanted = [str(x) for x in marker_labels]
        missing = sorted(set(wanted) - set(labels))
        if missing:
            raise InputError(f"marker_labels: the GLB has no marker node for {missing[:8]} "
                             f"(it has {len(labels)} marker nodes)", path=str(glb))
        labels = wanted
    size = glb.stat().st_size
    if embed is None:
        embed = size <= EMBED_LIMIT_BYTES
    out = Path(out_html)

    config: dict[str, Any] = {
        "title": title, "rate": rate_hz, "nFrames": n_frames, "markerLabels": labels,
        "background": _BACKGROUND, "glbUrl": None, "error": None,
    }
    data_scripts = []
    if embed:
        data_scripts.append('<script type="application/octet-stream" id="facecap-glb">'
                            + base64.b64encode(glb.read_bytes()).decode("ascii") + "</script>")
    else:
        relative = os.path.relpath(glb.resolve(), out.resolve().parent)
        config["glbUrl"] = urllib.parse.quote(Path(relative).as_posix())
    if error is not None:
        if vertex_source is not None:
            error = _through_vertex_source(error, vertex_source, summary["n_vertices"])
        levels, frames, (lo, hi) = _error_levels(error, summary["n_vertices"], n_frames, error_frames,
                                                 error_range_mm)
        config["error"] = {"n": summary["n_vertices"], "frames": frames, "range": [lo, hi], "unit": "mm",
                           "lut": _error_lut()}
        data_scripts.append('<script type="application/octet-stream" id="facecap-error">'
                            + base64.b64encode(levels.tobytes()).decode("ascii") + "</script>")

    modules = "\n".join(f'<script type="text/x-facecap-module" data-specifier="{spec}">\n{source}\n</script>'
                        for spec, source in _module_sources())
    review = _DATA / "review"
    facts = f"{n_frames} frames at {rate_hz:g} Hz ({(n_frames - 1) / rate_hz:.2f} s)"
    if labels:
        facts += f", {len(labels)} markers"
    values = {
        "version": __version__,
        "three_revision": _THREE_REVISION,
        "title": html_lib.escape(title),
        "facts": html_lib.escape(facts),
        "last_frame": str(n_frames - 1),
        "css": _script_safe((review / "review.css").read_text(encoding="utf-8"), review / "review.css"),
        "config": _json_for_script(config),
        "data": "\n".join(data_scripts),
        "modules": modules,
        "bootstrap": _script_safe((review / "bootstrap.js").read_text(encoding="utf-8"), review / "bootstrap.js"),
        "app": _script_safe((review / "review.js").read_text(encoding="utf-8"), review / "review.js"),
    }
    template = (review / "review.html").read_text(encoding="utf-8")
    page = re.sub(r"\{\{(\w+)\}\}", lambda m: values[m.group(1)], template)
    with atomic_path(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return out


class _QuietHandler(SimpleHTTPRequestHandler):
    """Static files from one folder, without a log line per request, with glTF's MIME types."""

    extensions_map = {
        **SimpleHTTPRequestHandler.extensions_map,
        ".glb": "model/gltf-binary",
        ".gltf": "model/gltf+json",
        ".js": "text/javascript",
        ".html": "text/html; charset=utf-8",
    }

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the base class's name
        pass

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-store")  # a re-run's files, not the browser's old copy
        super().end_headers()


class ReviewServer(ThreadingHTTPServer):
    """The local server of :func:`serve`: ``url`` to open, ``stop()`` to end it."""

    daemon_threads = True
    url: str
    thread: threading.Thread

    def stop(self) -> None:
        """Stop serving and close the socket (waits for the serving thread)."""
        self.shutdown()
        self.server_close()
        self.thread.join(timeout=5)


def serve(
    folder: str | os.PathLike[str],
    port: int = 0,
    *,
    page: str | None = "review.html",
    block: bool = False,
    quiet: bool = False,
) -> ReviewServer:
    """Serve a folder on ``http://127.0.0.1:<port>/`` (stdlib, threaded) and print the page's URL.

    Parameters
    ----------
    folder : str or path-like
        Folder to serve (the review page and the GLB it links); nothing outside it is served.
    port : int, optional
        TCP port on 127.0.0.1; default 0 picks a free one.
    page : str or None, optional
        File in ``folder`` whose URL is printed and stored in ``url``, default ``'review.html'``;
        None (or a page that does not exist) gives the folder's URL.
    block : bool, optional
        Serve until Ctrl-C, then stop (``facecap view``); default False serves from a daemon
        thread and returns at once.
    quiet : bool, optional
        Do not print the URL.

    Returns
    -------
    ReviewServer
        The running server (``url``, ``server_address``, ``stop()``); already stopped when ``block``.

    Raises
    ------
    InputError
        If ``folder`` is not a folder or the port cannot be bound.
    """
    root = Path(folder)
    if not root.is_dir():
        raise InputError("not a folder", path=str(root))
    if isinstance(port, bool) or not isinstance(port, (int, np.integer)) or not 0 <= port <= 65535:
        raise InputError(f"port: expected an integer in [0, 65535], got {port!r}")
    handler = functools.partial(_QuietHandler, directory=str(root.resolve()))
    try:
        server = ReviewServer(("127.0.0.1", int(port)), handler)
    except OSError as exc:
        raise InputError(f"port {port}: cannot listen on 127.0.0.1 ({exc.strerror or exc})") from None
    host, bound = server.server_address[:2]
    url = f"http://{host}:{bound}/"
    if page and (root / page).is_file():
        url += urllib.parse.quote(page)
    server.url = url
    server.thread = threading.Thread(target=server.serve_forever, name="facecap-review-server", daemon=True)
    server.thread.start()
    if not quiet:
        print(f"serving {root} at {url} (Ctrl-C to stop)" if block else f"serving {root} at {url}", flush=True)
    if block:
        try:
            while server.thread.is_alive():
                server.thread.join(timeout=0.5)
        except KeyboardInterrupt:
            pass
        finally:
            server.stop()
    return server
