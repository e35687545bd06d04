"""Images out, written with zlib and struct only: PNG files, animated PNGs (APNG) and an HTML flipbook of frames.

The flipbook's HTML shows its frames as one animated PNG in an ``<img>``: that plays where script is stripped or
never runs (an untrusted Jupyter notebook, whose sanitiser keeps ``<img src="data:...">`` and drops ``<script>``;
static notebook views such as GitHub's), since every current browser animates APNG (Firefox, Safari, Chrome and
Edge). Where script runs (a trusted notebook, nbviewer, a saved page, VS Code) a small player splits the same APNG
into its frames and adds play and pause, a slider and each frame's time: the frames are stored once.
"""
from __future__ import annotations

import base64
import hashlib
import html
import itertools
import json
import math
import pathlib
import struct
import zlib
from fractions import Fraction

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
# APNG

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: chunks that say nothing about pixels: frames may differ in them (the first frame's are kept)
_TEXT_CHUNKS = {b"tEXt", b"zTXt", b"iTXt", b"tIME"}


def _png_chunks(data: bytes, name: str = "frames") -> list:
    """[(kind, body)] of every chunk of a PNG file, its signature, lengths and CRCs checked."""
    if not isinstance(data, bytes) or not data.startswith(_SIGNATURE):
        raise checks.fail(name, data[:16] if isinstance(data, bytes) else type(data).__name__,
                          "each frame must be an image array or the bytes of a PNG file")
    chunks, offset = [], len(_SIGNATURE)
    while offset + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[offset:offset + 8])
        body = data[offset + 8:offset + 8 + length]
        crc = data[offset + 8 + length:offset + 12 + length]
        if len(body) != length or crc != struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF):
            raise checks.fail(name, f"a damaged {kind!r} chunk", "a PNG file with intact chunks")
        chunks.append((kind, body))
        offset += 12 + length
        if kind == b"IEND":
            break
    if not chunks or chunks[0][0] != b"IHDR" or chunks[-1][0] != b"IEND" or not any(k == b"IDAT" for k, _ in chunks):
        raise checks.fail(name, "a PNG file without IHDR, IDAT or IEND", "a complete PNG file")
    return chunks


def _frame_parts(data: bytes, index: int):
    """(the chunks before the first IDAT but IHDR, text and time chunks; IHDR's body; the image data)."""
    chunks = _png_chunks(data, f"frames[{index}]")
    if any(kind in (b"acTL", b"fcTL", b"fdAT") for kind, _ in chunks):
        raise checks.fail(f"frames[{index}]", "an animated PNG", "each frame a still PNG file or image array")
    first = next(i for i, (kind, _) in enumerate(chunks) if kind == b"IDAT")
    header = [(kind, body) for kind, body in chunks[1:first] if kind not in _TEXT_CHUNKS]
    return header, chunks[0][1], b"".join(body for kind, body in chunks if kind == b"IDAT")


def _frame_delay(fps: float) -> tuple[int, int]:
    """A frame's duration 1/fps [s] as fcTL's (delay_num, delay_den), both 16-bit: exact for rates such as 30,
    12.5 or 29.97 (to 1/1000 frame per second), else the nearest such fraction."""
    rate = Fraction(fps).limit_denominator(1000) or Fraction(fps)
    delay = 1 / rate
    delay = delay.limit_denominator(max(1, 65535 // math.ceil(delay)))
    if delay.numerator == 0:                         # over 65535 frames a second
        return 1, 65535
    return min(delay.numerator, 65535), delay.denominator


def _animated_png(pngs: list, fps: float, loops: int = 0) -> bytes:
    """One APNG of still PNG files of one size and pixel format: each frame's compressed rows as they are (frame 0
    the default image, IDAT; the others fdAT), full frames replacing each other (dispose none, blend source)."""
    parts = [_frame_parts(p, k) for k, p in enumerate(pngs)]
    header, ihdr, _ = parts[0]
    for k, (other_header, other_ihdr, _) in enumerate(parts[1:], start=1):
        if other_ihdr != ihdr or other_header != header:
            raise checks.fail(f"frames[{k}]", "a PNG of another size, bit depth, colour type or palette than "
                              "frames[0]", "every frame in one pixel format (pass image arrays to have them "
                              "encoded alike)")
    width, height = struct.unpack(">II", ihdr[:8])
    num, den = _frame_delay(fps)
    out = [_SIGNATURE, _chunk(b"IHDR", ihdr), _chunk(b"acTL", struct.pack(">II", len(parts), loops))]
    out += [_chunk(kind, body) for kind, body in header]
    sequence = 0
    for k, (_, _, data) in enumerate(parts):
        out.append(_chunk(b"fcTL", struct.pack(">IIIIIHHBB", sequence, width, height, 0, 0, num, den, 0, 0)))
        sequence += 1
        if k == 0:
            out.append(_chunk(b"IDAT", data))
        else:
            out.append(_chunk(b"fdAT", struct.pack(">I", sequence) + data))
            sequence += 1
    out.append(_chunk(b"IEND", b""))
    return b"".join(out)


def _encoded(frames, level: int = 9) -> list:
    """PNG files of ``frames``: PNG bytes kept as they are, image arrays encoded alike (RGBA for all where any
    has alpha, so that they share one pixel format)."""
    if isinstance(frames, (np.ndarray, bytes)) or not hasattr(frames, "__iter__"):
        raise checks.fail("frames", type(frames).__name__, "expected a list of images or PNG bytes")
    items = [f if isinstance(f, bytes) else _image(f, "frames") for f in frames]
    alpha = any(not isinstance(f, bytes) and f.shape[2] == 4 for f in items)
    if alpha:
        opaque = np.uint8(255)
        items = [f if isinstance(f, bytes) or f.shape[2] == 4 else
                 np.concatenate([f, np.full(f.shape[:2] + (1,), opaque)], axis=2) for f in items]
    return [f if isinstance(f, bytes) else png_bytes(f, level) for f in items]


def apng_bytes(frames, fps: float = 30.0, loops: int = 0, level: int = 9) -> bytes:
    """The animated PNG file (APNG, bytes) of ``frames``: image arrays ((H, W, 3) RGB or (H, W, 4) RGBA uint8, or
    floats in 0..1) or still PNG files, all the same size; each shown 1/``fps`` s, the whole played ``loops`` times
    (0: for ever). Lossless: each frame's pixels are those of ``png_bytes(frame, level)``; PNG files are used as
    they are, and must then share one pixel format. A viewer without APNG support shows the first frame."""
    pngs = _encoded(frames, level)
    if not pngs:
        raise checks.fail("frames", pngs, "expected at least one frame")
    fps = checks.scalar("fps", fps, low=0.0, low_open=True)
    if isinstance(loops, bool) or not isinstance(loops, (int, np.integer)) or not 0 <= loops < 2 ** 31:
        raise checks.fail("loops", loops, "expected a whole number of plays, 0 for ever")
    return _animated_png(pngs, fps, int(loops))


# ---------------------------------------------------------------------------------------------------------------
# the flipbook

_FLIPBOOK_IDS = itertools.count()

#: splitAPNG(binary string of an APNG) -> [base64 PNG file of each frame]: the header chunks (IHDR, PLTE, ...; not
#: acTL), one IDAT of the frame's data (IDAT or fdAT less its sequence number), IEND. For frames from png_bytes
#: (one IDAT each), each is the frame's own PNG file byte for byte (tests/preview/test_apng.py runs it in node).
_SPLIT_APNG_JS = """\
function splitAPNG(bin) {
  var table = [];
  for (var n = 0; n < 256; n++) {
    var c = n;
    for (var b = 0; b < 8; b++) c = (c & 1) ? (0xEDB88320 ^ (c >>> 1)) : (c >>> 1);
    table[n] = c >>> 0;
  }
  function crc(s) {
    var c = 0xFFFFFFFF;
    for (var i = 0; i < s.length; i++) c = table[(c ^ s.charCodeAt(i)) & 255] ^ (c >>> 8);
    return (c ^ 0xFFFFFFFF) >>> 0;
  }
  function u32(i) {
    return ((bin.charCodeAt(i) << 24) | (bin.charCodeAt(i + 1) << 16) | (bin.charCodeAt(i + 2) << 8)
            | bin.charCodeAt(i + 3)) >>> 0;
  }
  function be(x) { return String.fromCharCode((x >>> 24) & 255, (x >>> 16) & 255, (x >>> 8) & 255, x & 255); }
  function chunk(type, data) { return be(data.length) + type + data + be(crc(type + data)); }
  var head = "", datas = [], data = null, started = false, pos = 8;
  while (pos + 12 <= bin.length) {
    var length = u32(pos), type = bin.substr(pos + 4, 4);
    if (type === "fcTL" || type === "IEND") {
      if (data !== null) datas.push(data);
      data = type === "fcTL" ? "" : null;
      started = true;
    } else if (type === "IDAT") {
      if (data !== null) data += bin.substr(pos + 8, length);   // an IDAT before any fcTL is no frame
      started = true;
    } else if (type === "fdAT") {
      if (data !== null) data += bin.substr(pos + 12, length - 4);
    } else if (!started && type !== "acTL") {
      head += bin.substr(pos, length + 12);
    }
    if (type === "IEND") break;
    pos += length + 12;
  }
  var out = [];
  for (var k = 0; k < datas.length; k++)
    out.push(btoa(bin.substr(0, 8) + head + chunk("IDAT", datas[k]) + chunk("IEND", "")));
  return out;
}
"""


class Flipbook:
    """An animation as a self-contained HTML snippet: an animated PNG, with a player where script runs.

    ``pngs``: the frames as PNG file bytes, in one pixel format; ``times`` [s] per frame; ``fps``: playback
    frames per second. ``apng`` is the animated PNG of the frames (each shown 1/fps s, looping), ``image`` the same
    as a PNGImage (an image/png output, no HTML). Jupyter shows the flipbook inline (``_repr_html_``): the APNG in
    an ``<img>``, which plays where script is stripped (untrusted notebooks, static notebook views), and a script
    that splits it into its frames and adds play and pause, a slider and each frame's time where script runs.
    ``html`` is the snippet; ``save(path)`` writes a page, or the APNG for a ``.png`` or ``.apng`` path."""

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
        self.apng = _animated_png(self.pngs, self.fps)
        digest = hashlib.sha1(self.apng).hexdigest()[:10]
        self.element_id = f"warp-sim-flipbook-{digest}-{next(_FLIPBOOK_IDS)}"

    def __len__(self) -> int:
        return len(self.pngs)

    @property
    def image(self) -> PNGImage:
        """The animated PNG as a PNGImage: ``display(book.image)`` stores an image/png output only."""
        return PNGImage(self.apng)

    @property
    def html(self) -> str:
        n, uid, title = len(self.pngs), self.element_id, html.escape(self.title)
        apng = base64.b64encode(self.apng).decode("ascii")
        span = f"t = {self.times[0]:.3f} to {self.times[-1]:.3f} s" if n > 1 else f"t = {self.times[0]:.3f} s"
        slider = max(self.width - 170, 60)
        return f"""<div id="{uid}" class="warp-sim-flipbook" style="display:inline-block;font:12px sans-serif">
<img src="data:image/png;base64,{apng}" width="{self.width}" height="{self.height}" alt="{title}: {n} frames"
 title="{title}" style="display:block;border:1px solid #ccc">
<div class="warp-sim-flipbook-caption" style="margin-top:4px;color:#555">{n} frames, {span}, \
played at {self.fps:g} fps</div>
<script type="text/javascript">
(function () {{
  var root = document.getElementById("{uid}");
  if (!root || !window.atob || !window.btoa) return;
{_SPLIT_APNG_JS}
  var img = root.querySelector("img"), caption = root.querySelector(".warp-sim-flipbook-caption");
  var frames;
  try {{ frames = splitAPNG(atob(img.getAttribute("src").split(",")[1])); }} catch (error) {{ return; }}
  if (frames.length !== {n}) return;       // the animated PNG plays on
  var times = {json.dumps([round(t, 6) for t in self.times])};
  var bar = document.createElement("div"), button = document.createElement("button");
  var slider = document.createElement("input"), label = document.createElement("span");
  bar.style.cssText = "margin-top:4px;white-space:nowrap";
  button.type = "button";
  button.style.width = "70px";
  slider.type = "range";
  slider.min = 0;
  slider.max = {n - 1};
  slider.step = 1;
  slider.value = 0;
  slider.style.cssText = "width:{slider}px;vertical-align:middle";
  label.style.fontFamily = "monospace";
  bar.appendChild(button);
  bar.appendChild(slider);
  bar.appendChild(label);
  if (caption) root.replaceChild(bar, caption); else root.appendChild(bar);
  var k = 0, timer = null;
  function show(i) {{
    k = (i + frames.length) % frames.length;
    img.src = "data:image/png;base64," + frames[k];
    slider.value = k;
    label.textContent = (k + 1) + "/" + frames.length + "  t = " + times[k].toFixed(3) + " s";
  }}
  function play() {{
    button.innerHTML = "&#10074;&#10074; pause";
    timer = setInterval(function () {{ show(k + 1); }}, {1000.0 / self.fps:.3f});
  }}
  function stop() {{
    if (timer !== null) {{ clearInterval(timer); timer = null; }}
    button.innerHTML = "&#9654; play";
  }}
  button.addEventListener("click", function () {{ if (timer !== null) stop(); else play(); }});
  slider.addEventListener("input", function () {{ stop(); show(parseInt(slider.value, 10)); }});
  show(0);
  play();
}})();
</script>
</div>"""

    def _repr_html_(self) -> str:
        return self.html

    def save(self, path) -> pathlib.Path:
        """Write the animated PNG (a ``.png`` or ``.apng`` path) or else a standalone HTML page holding the
        flipbook; returns the path."""
        path = pathlib.Path(path)
        if path.suffix.lower() in (".png", ".apng"):
            path.write_bytes(self.apng)
            return path
        path.write_text(f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(self.title)}"
                        f"</title></head>\n<body>\n{self.html}\n</body></html>\n", encoding="utf-8")
        return path

    def __repr__(self) -> str:
        return f"Flipbook({len(self)} frames of {self.width}x{self.height} px at {self.fps:g} fps)"


def _png_size(data: bytes):
    if not isinstance(data, bytes) or not data.startswith(_SIGNATURE) or data[12:16] != b"IHDR":
        raise checks.fail("frames", data[:16] if isinstance(data, bytes) else type(data).__name__,
                          "each frame must be an image array or the bytes of a PNG file")
    return struct.unpack(">II", data[16:24])


def flipbook(frames, fps: float = 30.0, times=None, title: str = "warp_sim preview") -> Flipbook:
    """A Flipbook of ``frames``: image arrays ((H, W, 3) uint8 or floats in 0..1) or PNG file bytes, all the
    same size; ``fps`` [frames per second] for playback; ``times`` [s] shown per frame (default k / fps)."""
    return Flipbook(_encoded(frames), fps=fps, times=times, title=title)
