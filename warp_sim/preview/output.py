"""Images out: PNG bytes written with zlib and struct only, and a self-contained HTML flipbook of frames."""
from __future__ import annotations

import base64
import hashlib
import html
import itertools
import json
import pathlib
import struct
import zlib

import numpy as np

from ..util import checks

# ---------------------------------------------------------------------------------------------------------------
# PNG


def _image(image, name: str = "image") -> np.ndarray:
    """``image`` as a C-contiguous uint8 (H, W, 3 or 4) array; floats are read as 0..1 and clipped."""
    array = np.asarray(image)
    if array.ndim == 2:
        array = np.repeat(array[..., None], 3, axis=2)
    if array.ndim != 3 or array.shape[2] not in (3, 4) or array.shape[0] < 1 or array.shape[1] < 1:
        raise checks.fail(name, array.shape, "expected an image array of shape (H, W), (H, W, 3) or (H, W, 4)")
    if array.dtype == np.uint8:
        return np.ascontiguousarray(array)
    if array.dtype.kind == "f":
        if not np.isfinite(array).all():
            raise checks.fail(name, "non-finite values", "a float image must hold finite values in 0..1")
        return (np.clip(array, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    raise checks.fail(name, array.dtype, "expected uint8 (0..255) or float (0..1) pixel values")


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png_bytes(image, level: int = 9) -> bytes:
    """The PNG file (bytes) of an (H, W, 3) RGB or (H, W, 4) RGBA image (uint8, or floats in 0..1; (H, W) grey
    is drawn as RGB): 8 bits per channel, no filter (type 0 on every row), zlib ``level`` 0..9."""
    array = _image(image)
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or not 0 <= level <= 9:
        raise checks.fail("level", level, "expected a zlib compression level 0..9")
    h, w, c = array.shape
    rows = np.concatenate([np.zeros((h, 1), dtype=np.uint8), array.reshape(h, w * c)], axis=1)
    header = struct.pack(">IIBBBBB", w, h, 8, 6 if c == 4 else 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(rows.tobytes(), level))
            + _chunk(b"IEND", b""))


class PNGImage:
    """One image that Jupyter shows inline (``_repr_png_``); ``png`` holds the file's bytes."""

    def __init__(self, image):
        self.png = image if isinstance(image, bytes) else png_bytes(image)
        if not self.png.startswith(b"\x89PNG\r\n\x1a\n"):
            raise checks.fail("image", self.png[:16], "bytes must be a PNG file")

    def _repr_png_(self) -> bytes:
        return self.png

    def save(self, path) -> pathlib.Path:
        path = pathlib.Path(path)
        path.write_bytes(self.png)
        return path


# ---------------------------------------------------------------------------------------------------------------
# the flipbook

_FLIPBOOK_IDS = itertools.count()


def _png_size(data: bytes):
    if not isinstance(data, bytes) or not data.startswith(b"\x89PNG\r\n\x1a\n") or data[12:16] != b"IHDR":
        raise checks.fail("frames", data[:16] if isinstance(data, bytes) else type(data).__name__,
                          "each frame must be an image array or the bytes of a PNG file")
    return struct.unpack(">II", data[16:24])


class Flipbook:
    """An animation as a self-contained HTML snippet: base64 PNG frames, a slider and a play button.

    ``pngs``: the frames as PNG file bytes; ``times`` [s] per frame; ``fps``: playback frames per second.
    Jupyter shows it inline (``_repr_html_``); ``html`` is the snippet, ``save(path)`` writes a page."""

    def __init__(self, pngs, fps: float = 30.0, times=None, title: str = "warp_sim preview"):
        self.pngs = list(pngs)
        if not self.pngs:
            raise checks.fail("frames", self.pngs, "expected at least one frame")
        sizes = {_png_size(p) for p in self.pngs}
        if len(sizes) != 1:
            raise checks.fail("frames", sorted(sizes), "every frame must have the same size")
        self.width, self.height = sizes.pop()
        self.fps = checks.scalar("fps", fps, low=0.0, low_open=True)
        if times is None:
            times = np.arange(len(self.pngs)) / self.fps
        self.times = [float(t) for t in checks.finite_array("times", times, (len(self.pngs),))]
        self.title = str(title)
        digest = hashlib.sha1(b"".join(self.pngs)).hexdigest()[:10]
        self.element_id = f"warp-sim-flipbook-{digest}-{next(_FLIPBOOK_IDS)}"

    def __len__(self) -> int:
        return len(self.pngs)

    @property
    def html(self) -> str:
        frames = [base64.b64encode(p).decode("ascii") for p in self.pngs]
        n, uid, title = len(frames), self.element_id, html.escape(self.title)
        slider = max(self.width - 170, 60)
        return f"""<div id="{uid}" class="warp-sim-flipbook" style="display:inline-block;font:12px sans-serif">
<img src="data:image/png;base64,{frames[0]}" width="{self.width}" height="{self.height}" alt="{title}, frame 1 of {n}"
 title="{title}" style="display:block;border:1px solid #ccc">
<div style="margin-top:4px;white-space:nowrap">
<button type="button" style="width:70px">&#9654; play</button>
<input type="range" min="0" max="{n - 1}" value="0" step="1" style="width:{slider}px;vertical-align:middle">
<span style="font-family:monospace">1/{n}</span>
</div>
<script type="text/javascript">
(function () {{
  var root = document.getElementById("{uid}");
  if (!root) return;
  var frames = {json.dumps(frames)};
  var times = {json.dumps([round(t, 6) for t in self.times])};
  var img = root.querySelector("img"), button = root.querySelector("button");
  var slider = root.querySelector("input"), label = root.querySelector("span");
  var k = 0, timer = null;
  function show(i) {{
    k = (i + frames.length) % frames.length;
    img.src = "data:image/png;base64," + frames[k];
    slider.value = k;
    label.textContent = (k + 1) + "/" + frames.length + "  t = " + times[k].toFixed(3) + " s";
  }}
  function stop() {{
    if (timer !== null) {{ clearInterval(timer); timer = null; }}
    button.innerHTML = "&#9654; play";
  }}
  button.addEventListener("click", function () {{
    if (timer !== null) {{ stop(); return; }}
    button.innerHTML = "&#10074;&#10074; pause";
    timer = setInterval(function () {{ show(k + 1); }}, {1000.0 / self.fps:.3f});
  }});
  slider.addEventListener("input", function () {{ stop(); show(parseInt(slider.value, 10)); }});
  show(0);
}})();
</script>
</div>"""

    def _repr_html_(self) -> str:
        return self.html

    def save(self, path) -> pathlib.Path:
        """Write a standalone HTML page holding the flipbook; returns the path."""
        path = pathlib.Path(path)
        path.write_text(f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(self.title)}"
                        f"</title></head>\n<body>\n{self.html}\n</body></html>\n", encoding="utf-8")
        return path

    def __repr__(self) -> str:
        return f"Flipbook({len(self)} frames of {self.width}x{self.height} px at {self.fps:g} fps)"


def flipbook(frames, fps: float = 30.0, times=None, title: str = "warp_sim preview") -> Flipbook:
    """A Flipbook of ``frames``: image arrays ((H, W, 3) uint8 or floats in 0..1) or PNG file bytes, all the
    same size; ``fps`` [frames per second] for playback; ``times`` [s] shown per frame (default k / fps)."""
    if isinstance(frames, (np.ndarray, bytes)) or not hasattr(frames, "__iter__"):
        raise checks.fail("frames", type(frames).__name__, "expected a list of images or PNG bytes")
    pngs = [f if isinstance(f, bytes) else png_bytes(_image(f, "frames")) for f in frames]
    return Flipbook(pngs, fps=fps, times=times, title=title)

