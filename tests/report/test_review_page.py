"""The review page and the HTML report in a real browser (Debian's headless Chromium, SwiftShader WebGL).

Truth: a small GLB written here with pygltflib from known arrays (a face-like cap with two
morph targets, a weights animation and three animated marker nodes); the page must show those
weights and marker positions at each frame, and its picture of a frame must have the same
silhouette as facecap's own renderer draws for that frame's mesh from the same orthographic camera.
"""

from __future__ import annotations

import base64
import io
import json
import re
import struct
import time
import urllib.request
from pathlib import Path

import numpy as np
import pygltflib
import pytest
from matplotlib import colormaps
from matplotlib.image import imread

from facecap.errors import InputError
from facecap.io import write_gltf
from facecap.report import render_mesh, serve, write_html_report, write_review_page
from facecap.report import review_page as review_page_module
from facecap.structures import Mesh

from browser import launch_browser, open_page

RATE = 24.0
N_FRAMES = 48
LABELS = ["brow", "nose", "chin"]
KEY_FRAME = 30
"""A frame where both morph targets are well on, so its silhouette differs clearly from the rest shape's."""


def _cap_mesh() -> tuple[np.ndarray, np.ndarray]:
    """A face-sized cap (metres, as glTF): an elliptical patch of a bulged grid facing +z."""
    xs, ys = np.meshgrid(np.linspace(-0.045, 0.045, 37), np.linspace(-0.06, 0.06, 49))
    inside = (xs / 0.045) ** 2 + (ys / 0.06) ** 2 <= 1.0
    z = 0.03 * np.cos(0.5 * np.pi * np.clip(np.hypot(xs / 0.045, ys / 0.06), 0, 1))
    grid = np.stack([xs, ys, z], axis=-1)
    rows, cols = xs.shape
    index = -np.ones((rows, cols), np.int64)
    index[inside] = np.arange(inside.sum())
    faces = []
    for r in range(rows - 1):
        for c in range(cols - 1):
            a, b, d, e = index[r, c], index[r, c + 1], index[r + 1, c], index[r + 1, c + 1]
            if min(a, b, e) >= 0:
                faces.append((a, b, e))  # counter-clockwise seen from +z
            if min(a, e, d) >= 0:
                faces.append((a, e, d))
    return grid[inside].astype(np.float32), np.array(faces, np.uint32)


def _morph_targets(V: np.ndarray) -> np.ndarray:
    """Two targets that change the outline: the chin drops, the upper face widens."""
    jaw = np.zeros_like(V)
    jaw[:, 1] = -0.5 * np.clip(-V[:, 1] - 0.01, 0, None)
    wide = np.zeros_like(V)
    wide[:, 0] = 0.35 * V[:, 0] * (V[:, 1] > 0)
    return np.stack([jaw, wide])


def _weights() -> np.ndarray:
    t = np.arange(N_FRAMES) / (N_FRAMES - 1)
    return np.stack([np.sin(np.pi * t) ** 2, np.clip(2 * t - 0.5, 0, 1)], axis=1).astype(np.float32)


def _marker_tracks(V: np.ndarray) -> np.ndarray:
    """(3, T, 3) marker positions following three mesh vertices, pushed 2 mm off the surface."""
    D = _morph_targets(V)
    W = _weights()
    picks = [int(np.argmax(V[:, 1] - 10 * np.abs(V[:, 0]))), int(np.argmax(V[:, 2])),
             int(np.argmin(V[:, 1] + 10 * np.abs(V[:, 0])))]
    tracks = []
    for i in picks:
        path = V[i] + W @ D[:, i]
        tracks.append(path + np.array([0, 0, 0.002], np.float32))
    return np.array(tracks, np.float32)


def _frame_vertices(V: np.ndarray, k: int) -> np.ndarray:
    return V + np.tensordot(_weights()[k], _morph_targets(V), axes=1)


def write_test_glb(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Write the test GLB with pygltflib from known arrays; return (V, F) of its rest mesh."""
    V, F = _cap_mesh()
    D = _morph_targets(V).astype(np.float32)
    W = _weights()
    times = (np.arange(N_FRAMES) / RATE).astype(np.float32)
    tracks = _marker_tracks(V)
    blobs: list[bytes] = []
    views: list[pygltflib.BufferView] = []
    accessors: list[pygltflib.Accessor] = []

    def add(array: np.ndarray, kind: str, component: int, *, target: int | None = None, bounds: bool = False) -> int:
        offset = sum(len(b) for b in blobs)
        data = np.ascontiguousarray(array).tobytes()
        blobs.append(data + b"\0" * (-len(data) % 4))
        views.append(pygltflib.BufferView(buffer=0, byteOffset=offset, byteLength=len(data), target=target))
        flat = array.reshape(array.shape[0], -1) if array.ndim > 1 else array.reshape(-1, 1)
        accessors.append(pygltflib.Accessor(
            bufferView=len(views) - 1, componentType=component,
            count=int(array.size if kind == "SCALAR" else array.shape[0]), type=kind,
            min=flat.min(axis=0).tolist() if bounds else None, max=flat.max(axis=0).tolist() if bounds else None))
        return len(accessors) - 1

    position = add(V, "VEC3", pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER, bounds=True)
    indices = add(F.reshape(-1), "SCALAR", pygltflib.UNSIGNED_INT, target=pygltflib.ELEMENT_ARRAY_BUFFER)
    targets = [{"POSITION": add(d, "VEC3", pygltflib.FLOAT, target=pygltflib.ARRAY_BUFFER, bounds=True)} for d in D]
    time_acc = add(times, "SCALAR", pygltflib.FLOAT, bounds=True)
    weight_acc = add(W.reshape(-1), "SCALAR", pygltflib.FLOAT)
    track_accs = [add(tr, "VEC3", pygltflib.FLOAT) for tr in tracks]

    primitive = pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=position), indices=indices,
                                    targets=targets, mode=pygltflib.TRIANGLES)
    mesh = pygltflib.Mesh(name="face", primitives=[primitive], weights=[0.0, 0.0],
                          extras={"targetNames": ["jaw", "wide"]})
    nodes = [pygltflib.Node(name="face", mesh=0)]
    nodes += [pygltflib.Node(name=f"marker:{label}", translation=tracks[i, 0].tolist())
              for i, label in enumerate(LABELS)]
    samplers = [pygltflib.AnimationSampler(input=time_acc, output=weight_acc, interpolation="LINEAR")]
    channels = [pygltflib.AnimationChannel(sampler=0, target=pygltflib.AnimationChannelTarget(node=0, path="weights"))]
    for i, acc in enumerate(track_accs):
        samplers.append(pygltflib.AnimationSampler(input=time_acc, output=acc, interpolation="LINEAR"))
        channels.append(pygltflib.AnimationChannel(
            sampler=i + 1, target=pygltflib.AnimationChannelTarget(node=i + 1, path="translation")))
    blob = b"".join(blobs)
    gltf = pygltflib.GLTF2(
        asset=pygltflib.Asset(version="2.0", generator="facecap tests"),
        scene=0, scenes=[pygltflib.Scene(nodes=list(range(len(nodes))))], nodes=nodes, meshes=[mesh],
        accessors=accessors, bufferViews=views, buffers=[pygltflib.Buffer(byteLength=len(blob))],
        animations=[pygltflib.Animation(name="take", samplers=samplers, channels=channels)],
    )
    gltf.set_binary_blob(blob)
    gltf.save_binary(str(path))
    return V, F.astype(np.int64)


def write_facecap_glb(path: Path, *, compress: bool = False) -> dict:
    """The same take through facecap's own writer (millimetres in, metres in the file, a "Markers" group)."""
    V, F = _cap_mesh()
    mesh = Mesh(V.astype(np.float64) * 1000.0, F.astype(np.int64))
    tracks = _marker_tracks(V)
    return write_gltf(path, mesh, targets=_morph_targets(V).astype(np.float64) * 1000.0, weights=_weights(),
                      rate=RATE, markers=tracks.transpose(1, 0, 2).astype(np.float64) * 1000.0,
                      marker_labels=LABELS, compress=compress)


@pytest.fixture(scope="module")
def browser():
    with launch_browser() as b:
        yield b


@pytest.fixture(scope="module")
def glb_case(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray, np.ndarray]:
    folder = tmp_path_factory.mktemp("review")
    write_facecap_glb(folder / "take.glb")
    write_facecap_glb(folder / "compressed.glb", compress=True)  # EXT_meshopt_compression
    V, F = write_test_glb(folder / "prefixed.glb")
    return folder, V, F


def _wait_ready(page: object) -> None:
    page.wait_for_function("window.facecapReview && (window.facecapReview.ready || window.facecapReview.loadError)",
                           timeout=20000)
    error = page.evaluate("window.facecapReview.loadError")
    assert error is None, error


def _png(data: bytes) -> np.ndarray:
    return imread(io.BytesIO(data), format="png")[..., :3]


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def test_page_plays_the_glb_offline_from_file(browser: object, glb_case: tuple, tmp_path: Path) -> None:
    folder, V, F = glb_case
    page_path = write_review_page(folder / "review.html", folder / "take.glb", title="test take", rate=RATE,
                                  n_frames=N_FRAMES)
    html = page_path.read_text()
    assert 'id="facecap-glb"' in html  # a small GLB is embedded: nothing else is needed beside the page
    with open_page(browser, page_path.as_uri()) as (page, watch):
        _wait_ready(page)
        assert page.evaluate("window.facecapReview.nFrames") == N_FRAMES
        assert page.evaluate("window.facecapReview.markerLabels()") == LABELS

        # Playing advances the frame counter.
        assert page.inner_text("#frame") == "0"
        page.click("#play")
        page.wait_for_function("Number(document.getElementById('frame').textContent) >= 3", timeout=10000)
        page.click("#play")  # pause
        assert not page.evaluate("window.facecapReview.playing()")

        # setFrame(k) shows frame k: the counter, the scrubber, the weights and markers of the file.
        truth_tracks = _marker_tracks(V)
        for k in (0, 17, KEY_FRAME, N_FRAMES - 1):
            page.evaluate(f"window.facecapReview.setFrame({k})")
            assert page.inner_text("#frame") == str(k)
            assert page.eval_on_selector("#scrubber", "e => Number(e.value)") == k
            assert page.evaluate("window.facecapReview.frame()") == k
            np.testing.assert_allclose(page.evaluate("window.facecapReview.morphWeights()"), _weights()[k],
                                       atol=1e-6)
            np.testing.assert_allclose(page.evaluate("window.facecapReview.markerPositions()"),
                                       truth_tracks[:, k], atol=1e-7)

        # The scrubber drives the frame too.
        page.eval_on_selector("#scrubber", "e => { e.value = '12'; e.dispatchEvent(new Event('input')); }")
        assert page.inner_text("#frame") == "12"

        # Silhouette of frame KEY_FRAME against facecap's renderer, same orthographic front window.
        width, height = page.evaluate("window.facecapReview.canvasSize()")
        Vk = _frame_vertices(V, KEY_FRAME).astype(np.float64)
        half_h = 0.095
        half_w = half_h * width / height
        cx, cy = 0.0, -0.01
        bounds = (cx - half_w, cx + half_w, cy - half_h, cy + half_h)
        page.evaluate("window.facecapReview.setMarkersVisible(false)")
        page.evaluate(f"window.facecapReview.setCamera({{left: {bounds[0]}, right: {bounds[1]}, "
                      f"bottom: {bounds[2]}, top: {bounds[3]}}})")
        page.evaluate(f"window.facecapReview.setFrame({KEY_FRAME})")
        shot = _png(page.locator("#canvas").screenshot())
        background = np.array([0x33, 0x37, 0x3D]) / 255
        page_mask = np.abs(shot - background).max(axis=2) > 0.06

        # The canvas's CSS box may be a fractional pixel taller than its drawing buffer: draw the
        # reference at the screenshot's size (the window's aspect differs by under 0.2 %).
        height, width = shot.shape[:2]
        render_mesh(Vk, F, tmp_path / "frame.png", bounds=bounds, size_px=(width, height))
        reference = imread(tmp_path / "frame.png")[..., :3]
        reference_mask = reference.min(axis=2) < 0.97
        render_mesh(V.astype(np.float64), F, tmp_path / "rest.png", bounds=bounds, size_px=(width, height))
        rest_mask = imread(tmp_path / "rest.png")[..., :3].min(axis=2) < 0.97

        iou = _iou(page_mask, reference_mask)
        assert shot.shape[:2] == reference.shape[:2] == (height, width)
        assert 0.05 < reference_mask.mean() < 0.8  # the face fills a good part of the view
        assert iou >= 0.95, iou
        assert _iou(page_mask, rest_mask) < 0.85  # the check can tell the key frame from the rest shape

        page.evaluate("window.facecapReview.resetCamera()")
        assert watch.problems() == []
        assert all(not u.startswith("http") for u in watch.requests)


def test_linked_glb_over_localhost(browser: object, glb_case: tuple, tmp_path: Path) -> None:
    folder, _, _ = glb_case
    site = tmp_path / "site"
    site.mkdir()
    (site / "take.glb").write_bytes((folder / "prefixed.glb").read_bytes())  # `marker:<label>` nodes
    page_path = write_review_page(site / "review.html", site / "take.glb", title="linked", rate=RATE,
                                  n_frames=N_FRAMES, embed=False)
    assert 'id="facecap-glb"' not in page_path.read_text()
    server = serve(site, quiet=True)
    try:
        assert server.server_address[0] == "127.0.0.1"
        assert server.url.endswith("/review.html")
        with open_page(browser, server.url) as (page, watch):
            _wait_ready(page)
            page.evaluate("window.facecapReview.setFrame(5)")
            assert page.inner_text("#frame") == "5"
            np.testing.assert_allclose(page.evaluate("window.facecapReview.morphWeights()"), _weights()[5],
                                       atol=1e-6)
            assert page.evaluate("window.facecapReview.markerLabels()") == LABELS
            np.testing.assert_allclose(page.evaluate("window.facecapReview.markerPositions()"),
                                       _marker_tracks(_cap_mesh()[0])[:, 5], atol=1e-7)
            assert watch.problems() == []
            assert any(u.endswith("/take.glb") for u in watch.requests)
    finally:
        server.stop()


def test_error_heat_map_colours_and_legend(browser: object, glb_case: tuple) -> None:
    folder, V, _ = glb_case
    n = V.shape[0]
    error = np.stack([np.zeros(n), np.full(n, 2.0)])  # row 0 (frames 0-19) at the low end, row 1 at the high
    page_path = write_review_page(folder / "error.html", folder / "compressed.glb", title="error", rate=RATE,
                                  n_frames=N_FRAMES, error=error, error_frames=[0, 20], error_range_mm=(0.0, 2.0))
    inferno = colormaps["inferno"]
    with open_page(browser, page_path.as_uri(), width=600, height=600) as (page, watch):
        _wait_ready(page)
        assert page.is_hidden("#legend")
        page.check("#error-toggle")
        assert page.is_visible("#legend")
        assert page.inner_text("#legend-high") == "2.00 mm"
        page.evaluate("window.facecapReview.setMarkersVisible(false)")
        for frame, expected in ((5, inferno(0.0)[:3]), (25, inferno(1.0)[:3])):
            page.evaluate(f"window.facecapReview.setFrame({frame})")
            shot = _png(page.locator("#canvas").screenshot())
            h, w = shot.shape[:2]
            centre = shot[h // 2 - 5:h // 2 + 5, w // 2 - 5:w // 2 + 5].reshape(-1, 3)
            np.testing.assert_allclose(centre.mean(axis=0), expected, atol=0.03)
            assert page.inner_text("#legend-frame") == f"error at frame {0 if frame < 20 else 20}"
            # The meshopt-compressed file decodes to the same animation.
            np.testing.assert_allclose(page.evaluate("window.facecapReview.morphWeights()"), _weights()[frame],
                                       atol=1e-6)
        page.uncheck("#error-toggle")
        shot = _png(page.locator("#canvas").screenshot())
        centre = shot[h // 2 - 5:h // 2 + 5, w // 2 - 5:w // 2 + 5].reshape(-1, 3).mean(axis=0)
        assert np.abs(centre - inferno(1.0)[:3]).max() > 0.2  # back to the neutral grey
        assert watch.problems() == []


def test_html_report_renders_and_links_to_the_page(browser: object, glb_case: tuple, tmp_path: Path) -> None:
    folder, _, _ = glb_case
    result = tmp_path / "result"
    result.mkdir()
    (result / "take.glb").write_bytes((folder / "take.glb").read_bytes())
    review = write_review_page(result / "review.html", result / "take.glb", title="take", rate=RATE,
                               n_frames=N_FRAMES)
    residual = np.abs(np.sin(np.arange(N_FRAMES) / 5.0)) * 0.3
    (result / "performance.json").write_text(json.dumps(
        {"rate": RATE, "n_frames": N_FRAMES, "n_vertices": 1234, "units": "mm",
         "timings": {"solve_s": 1.25, "total_s": 3.5}}))
    report = {"timings": {"deform_and_write_s": 2.75, "frames_per_second": np.float64(17.45)},
              "n_frames": N_FRAMES,
              "marker_residual_mm": {"per_frame_max": residual, "max": float(residual.max())},  # an array too
              "warp_leave_one_out_mm": {"brow": 0.12, "nose": 0.34},
              "evaluation": {"mean_mm": 0.21, "regions": {"eyes": {"mean_mm": 0.11, "max_mm": 0.5},
                                                           "mouth": {"mean_mm": 0.3, "max_mm": 0.93}}},
              "warnings": ["a <b>warning</b> with markup"]}
    picture = tmp_path / "picture.png"
    render_mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]), picture,
                size_px=(120, 90))
    out = write_html_report(result / "report.html", result, report=report, pictures=[picture],
                            review_page=review)
    html = out.read_text()
    assert "<b>warning</b>" not in html and "&lt;b&gt;warning&lt;/b&gt;" in html
    with open_page(browser, out.as_uri()) as (page, watch):
        page.wait_for_load_state("load")
        text = page.inner_text("body")
        for figure in ("2.75 s", "17.4", "1.25 s", "3.5 s", "1,234 vertices", "0.34 mm"):
            assert figure in text
        assert f"largest {residual.max():.3g} mm" in text
        rows = page.eval_on_selector_all("tr", "rows => rows.map(r => Array.from(r.cells, c => c.textContent))")
        # a figure facecap does not know is shown under a readable name, nested groups as 'group: name'
        assert ["Evaluation: regions: mouth: largest", "0.93 mm"] in rows
        assert ["nose", "0.34", ""] in rows  # the per-marker table
        sizes = page.eval_on_selector_all("img", "imgs => imgs.map(i => [i.alt, i.naturalWidth, i.naturalHeight])")
        assert ["picture.png", 120, 90] in sizes
        assert any(alt.startswith("plot: The largest marker residual") and w > 0 for alt, w, _ in sizes)
        link = page.locator("a#review-link")
        assert link.get_attribute("href") == "review.html"
        link.click()
        _wait_ready(page)
        assert page.evaluate("window.facecapReview.nFrames") == N_FRAMES
        assert watch.problems() == []


def test_embed_threshold_links_a_large_glb(glb_case: tuple, monkeypatch: pytest.MonkeyPatch) -> None:
    folder, _, _ = glb_case
    size = (folder / "take.glb").stat().st_size
    monkeypatch.setattr(review_page_module, "EMBED_LIMIT_BYTES", size - 1)
    html = write_review_page(folder / "big.html", folder / "take.glb", title="t", rate=RATE,
                             n_frames=N_FRAMES).read_text()
    assert 'id="facecap-glb"' not in html
    config = json.loads(re.search(r'id="facecap-config">(.*?)</script>', html).group(1))
    assert config["glbUrl"] == "take.glb"
    monkeypatch.setattr(review_page_module, "EMBED_LIMIT_BYTES", size)
    html = write_review_page(folder / "big.html", folder / "take.glb", title="t", rate=RATE,
                             n_frames=N_FRAMES).read_text()
    embedded = re.search(r'id="facecap-glb">([A-Za-z0-9+/=]*)</script>', html).group(1)
    assert base64.b64decode(embedded) == (folder / "take.glb").read_bytes()


def test_error_quantisation_and_the_page_needs_nothing_from_outside(glb_case: tuple) -> None:
    folder, V, _ = glb_case
    n = V.shape[0]
    error = np.linspace(0.0, 4.0, n)
    error[3] = np.nan
    html = write_review_page(folder / "q.html", folder / "take.glb", title="t", rate=RATE, n_frames=N_FRAMES,
                             error=error, error_range_mm=(0.0, 2.0)).read_text()
    levels = np.frombuffer(base64.b64decode(re.search(r'id="facecap-error">([^<]*)<', html).group(1)), np.uint8)
    expected = np.round(np.clip(error / 2.0, 0, 1) * 254)
    expected[3] = 255
    np.testing.assert_array_equal(levels, expected)
    # No address outside the page: every src/href is absent and no http(s) URL is fetched.
    addresses = re.findall(r'<(?:script|link|img|a)[^>]+(?:src|href)="([^"]*)"', html)
    assert addresses and all(a.startswith("data:") for a in addresses), addresses


def test_error_on_the_mesh_follows_write_gltfs_seam_split(tmp_path: Path) -> None:
    # Two triangles sharing the edge 0-2, with different UVs there on each side: a seam.
    V = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0.5, 0], [0.5, 1], [0, 1]], float)
    mesh = Mesh(V, F, uvs=uvs, uv_indices=np.array([0, 1, 2, 3, 4, 5]))
    info = write_gltf(tmp_path / "seam.glb", mesh, targets=np.ones((1, 4, 3)), weights=[[0.0], [1.0]], rate=RATE)
    source = info["vertex_source"]
    assert source.size == 6 and sorted(set(source.tolist())) == [0, 1, 2, 3]  # vertices 0 and 2 were split
    error = np.array([0.0, 1.0, 2.0, 3.0])
    html = write_review_page(tmp_path / "seam.html", tmp_path / "seam.glb", title="t", rate=RATE, n_frames=2,
                             error=error, vertex_source=source, error_range_mm=(0.0, 3.0)).read_text()
    levels = np.frombuffer(base64.b64decode(re.search(r'id="facecap-error">([^<]*)<', html).group(1)), np.uint8)
    np.testing.assert_array_equal(levels, np.round(error[source] / 3.0 * 254))
    with pytest.raises(InputError, match="GLB's mesh"):  # on the mesh's 4 vertices, without the map
        write_review_page(tmp_path / "seam.html", tmp_path / "seam.glb", title="t", rate=RATE, n_frames=2,
                          error=error)


def test_serve_serves_the_folder_on_loopback_only(tmp_path: Path) -> None:
    (tmp_path / "take.glb").write_bytes(b"glTF-bytes")
    server = serve(tmp_path, port=0, page=None, quiet=True)
    try:
        host, port = server.server_address[:2]
        assert host == "127.0.0.1" and port > 0
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/take.glb", timeout=5) as response:
            assert response.read() == b"glTF-bytes"
            assert response.headers["Content-Type"] == "model/gltf-binary"
    finally:
        server.stop()
    started = time.perf_counter()
    with pytest.raises(OSError):
        urllib.request.urlopen(f"http://127.0.0.1:{port}/take.glb", timeout=2)
    assert time.perf_counter() - started < 3


def test_bad_input_is_named(glb_case: tuple, tmp_path: Path) -> None:
    folder, V, _ = glb_case
    glb = folder / "take.glb"
    with pytest.raises(InputError, match="GLB not found"):
        write_review_page(tmp_path / "a.html", tmp_path / "none.glb", title="t", rate=RATE, n_frames=3)
    (tmp_path / "fake.glb").write_bytes(struct.pack("<4sIIII", b"glTF", 1, 20, 0, 0))
    with pytest.raises(InputError, match="glTF 2.0"):
        write_review_page(tmp_path / "a.html", tmp_path / "fake.glb", title="t", rate=RATE, n_frames=3)
    with pytest.raises(InputError, match="rate"):
        write_review_page(tmp_path / "a.html", glb, title="t", rate=0, n_frames=3)
    with pytest.raises(InputError, match="n_frames"):
        write_review_page(tmp_path / "a.html", glb, title="t", rate=RATE, n_frames=0)
    with pytest.raises(InputError, match="'ear'"):
        write_review_page(tmp_path / "a.html", glb, title="t", rate=RATE, n_frames=3, marker_labels=["nose", "ear"])
    with pytest.raises(InputError, match=f"\\({V.shape[0]},\\)"):
        write_review_page(tmp_path / "a.html", glb, title="t", rate=RATE, n_frames=3, error=np.zeros(5))
    with pytest.raises(InputError, match="error_frames"):
        write_review_page(tmp_path / "a.html", glb, title="t", rate=RATE, n_frames=3,
                          error=np.zeros((2, V.shape[0])), error_frames=[0, 7])
    assert not (tmp_path / "a.html").exists()
    with pytest.raises(InputError, match="not a folder"):
        serve(tmp_path / "missing", quiet=True)
