"""warp_sim.preview's animated PNG (APNG) and the flipbook that shows it: its chunks decoded here with zlib and struct
(signature, CRCs, acTL's frame count, fcTL's sequence numbers, sizes and delays, one fdAT per later frame), each
frame's rows decompressed and compared with the frame put in, with a tolerance of zero (the format is lossless);
the flipbook's script, run in node where node is installed, splits the APNG back into the frames' PNG files; and
Pillow, where installed, reads the same frames, durations and loop count."""
import base64
import io
import json
import re
import shutil
import struct
import subprocess
import zlib

import numpy as np
import pytest

from warp_sim import preview
from warp_sim.preview import output

W, H = 37, 23   # odd sizes: no row or frame lines up with anything by chance


def chunks_of(data: bytes) -> list[tuple[bytes, bytes]]:
    """[(kind, body)] of a PNG or APNG file; checks the signature, every length and every CRC."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "bad PNG signature"
    offset, chunks = 8, []
    while offset < len(data):
        length, kind = struct.unpack(">I4s", data[offset:offset + 8])
        body = data[offset + 8:offset + 8 + length]
        assert len(body) == length, f"{kind!r} runs past the end"
        (crc,) = struct.unpack(">I", data[offset + 8 + length:offset + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, f"bad CRC in {kind!r}"
        chunks.append((kind, body))
        offset += 12 + length
    assert offset == len(data)
    return chunks


def decode_apng(data: bytes):
    """(frames as (H, W, C) uint8 arrays, [(delay_num, delay_den)], num_plays) of an APNG of full frames of 8-bit
    RGB or RGBA rows without filters, checking the layout warp_sim writes and the APNG specification requires:
    IHDR first, acTL before any image data, fcTL before each frame's data (frame 0's in IDAT, the others' in
    fdAT), sequence numbers 0, 1, 2, ... over fcTL and fdAT together, IEND last."""
    chunks = chunks_of(data)
    assert chunks[0][0] == b"IHDR" and chunks[-1] == (b"IEND", b"")
    width, height, depth, colour, compression, filtering, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    assert (depth, compression, filtering, interlace) == (8, 0, 0, 0) and colour in (2, 6)
    channels = 3 if colour == 2 else 4
    kinds = [kind for kind, _ in chunks]
    assert kinds.count(b"acTL") == 1 and kinds.index(b"acTL") < kinds.index(b"IDAT")
    num_frames, num_plays = struct.unpack(">II", dict(chunks)[b"acTL"])
    sequence, frames, delays = [], [], []
    for kind, body in chunks[1:]:
        if kind == b"fcTL":
            seq, w, h, x, y, num, den, dispose, blend = struct.unpack(">IIIIIHHBB", body)
            assert (w, h, x, y, dispose, blend) == (width, height, 0, 0, 0, 0), "a full frame replacing the last"
            sequence.append(seq)
            delays.append((num, den))
            frames.append([])
        elif kind == b"IDAT":
            assert len(frames) == 1, "IDAT is frame 0 (after its fcTL), and only frame 0"
            frames[-1].append(body)
        elif kind == b"fdAT":
            assert len(frames) > 1, "fdAT holds the later frames"
            sequence.append(struct.unpack(">I", body[:4])[0])
            frames[-1].append(body[4:])
    assert sequence == list(range(len(sequence))), f"sequence numbers {sequence}"
    assert len(frames) == num_frames, f"acTL says {num_frames} frames, fcTL gives {len(frames)}"
    images = []
    for parts in frames:
        raw = zlib.decompress(b"".join(parts))
        assert len(raw) == height * (1 + width * channels), "a frame decompresses to the wrong size"
        rows = np.frombuffer(raw, dtype=np.uint8).reshape(height, 1 + width * channels)
        assert not rows[:, 0].any(), "filter type 0 on every row"
        images.append(rows[:, 1:].reshape(height, width, channels))
    return images, delays, num_plays


def random_frames(count: int, channels: int = 3, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (H, W, channels), dtype=np.uint8) for _ in range(count)]


@pytest.mark.parametrize("channels", [3, 4])
def test_apng_frames_are_the_frames_put_in(channels):
    frames = random_frames(7, channels)
    images, delays, plays = decode_apng(preview.apng_bytes(frames, fps=12.5))
    assert len(images) == 7 and plays == 0
    for put, got in zip(frames, images):
        np.testing.assert_array_equal(got, put)              # tolerance zero: lossless
    assert set(delays) == {(2, 25)}                          # 1/12.5 s exactly


def test_apng_from_png_files_reuses_their_compressed_rows():
    frames = random_frames(3)
    pngs = [preview.png_bytes(f, level=1) for f in frames]
    apng = preview.apng_bytes(pngs, fps=30, loops=2)
    images, delays, plays = decode_apng(apng)
    for put, got in zip(frames, images):
        np.testing.assert_array_equal(got, put)
    assert plays == 2 and set(delays) == {(1, 30)}
    idat = [b"".join(body for kind, body in chunks_of(p) if kind == b"IDAT") for p in pngs]
    stored = [body for kind, body in chunks_of(apng) if kind == b"IDAT"]
    stored += [body[4:] for kind, body in chunks_of(apng) if kind == b"fdAT"]
    assert stored == idat                                    # not decoded and encoded again


def test_one_frame_is_an_animation_of_one_frame():
    images, _, _ = decode_apng(preview.apng_bytes(random_frames(1), fps=24))
    assert len(images) == 1


def test_float_frames_and_mixed_alpha_are_encoded_alike():
    rgb = np.linspace(0.0, 1.0, H * W * 3).reshape(H, W, 3)
    rgba = random_frames(1, 4)[0]
    images, _, _ = decode_apng(preview.apng_bytes([rgb, rgba], fps=10))
    np.testing.assert_array_equal(images[0][..., :3], (rgb * 255.0 + 0.5).astype(np.uint8))
    np.testing.assert_array_equal(images[0][..., 3], 255)   # opaque where the frame had no alpha
    np.testing.assert_array_equal(images[1], rgba)


@pytest.mark.parametrize("fps, delay", [(30, (1, 30)), (29.97, (100, 2997)), (12.5, (2, 25)), (1 / 3, (3, 1)),
                                        (1e6, (1, 65535))])
def test_frame_delay(fps, delay):
    assert output._frame_delay(fps) == delay


@pytest.mark.parametrize("call", [
    lambda: preview.apng_bytes([]),
    lambda: preview.apng_bytes(random_frames(2), fps=0),
    lambda: preview.apng_bytes(random_frames(2), loops=-1),
    lambda: preview.apng_bytes([preview.png_bytes(random_frames(1, 3)[0]), preview.png_bytes(random_frames(1, 4)[0])]),
    lambda: preview.apng_bytes([preview.apng_bytes(random_frames(2))]),
    lambda: preview.apng_bytes([preview.png_bytes(random_frames(1)[0])[:-5]]),
], ids=["empty", "fps", "loops", "formats", "animated", "truncated"])
def test_bad_input(call):
    with pytest.raises(ValueError):
        call()


# -- the flipbook ------------------------------------------------------------------------------------------------

def img_src(page: str) -> bytes:
    return base64.b64decode(re.search(r'<img src="data:image/png;base64,([^"]+)"', page).group(1))


def test_flipbook_shows_the_apng_without_script():
    frames = random_frames(5)
    book = preview.flipbook(frames, fps=10)
    page = book._repr_html_()
    assert page == book.html and "warp-sim-flipbook" in page
    apng = img_src(page)
    assert apng == book.apng == book.image._repr_png_()
    images, delays, _ = decode_apng(apng)
    for put, got in zip(frames, images):
        np.testing.assert_array_equal(got, put)
    assert set(delays) == {(1, 10)}
    static = re.sub(r"<script.*?</script>", "", page, flags=re.S)      # what a sanitiser leaves
    assert "<img" in static and "5 frames" in static and "<button" not in static and "<input" not in static
    assert page.count("data:image/png;base64,") == 2      # the APNG, and the player's prefix for its frames


def test_flipbook_saves_a_page_or_the_apng(tmp_path):
    book = preview.flipbook(random_frames(3), fps=10)
    assert book.save(tmp_path / "clip.png").read_bytes() == book.apng
    page = book.save(tmp_path / "clip.html").read_text()
    assert page.startswith("<!DOCTYPE html>") and img_src(page) == book.apng


NODE = shutil.which("node")


@pytest.mark.skipif(NODE is None, reason="node is not installed")
@pytest.mark.parametrize("channels", [3, 4])
def test_player_splits_the_apng_into_the_frames_png_files(channels):
    frames = random_frames(4, channels, seed=channels)
    book = preview.flipbook(frames, fps=10)
    script = re.search(r"<script[^>]*>(.*?)</script>", book.html, flags=re.S).group(1)
    assert output._SPLIT_APNG_JS in script
    program = output._SPLIT_APNG_JS + """
let input = "";
process.stdin.on("data", (d) => { input += d; });
process.stdin.on("end", () => { console.log(JSON.stringify(splitAPNG(atob(input.trim())))); });
"""
    done = subprocess.run([NODE, "-e", program], input=base64.b64encode(book.apng).decode("ascii"),
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    split = [base64.b64decode(text) for text in json.loads(done.stdout)]
    assert split == book.pngs                                # byte for byte: the frames' own PNG files


@pytest.mark.parametrize("channels", [3, 4])
def test_an_independent_decoder_reads_the_same_frames(channels):
    """Pillow (there with matplotlib, not a dependency) reads APNG: its frames, durations and loop count agree."""
    image = pytest.importorskip("PIL.Image")
    frames = random_frames(6, channels, seed=10 + channels)
    with image.open(io.BytesIO(preview.apng_bytes(frames, fps=25))) as apng:
        assert apng.format == "PNG" and apng.n_frames == 6 and apng.is_animated
        assert apng.info.get("loop") == 0
        for k, frame in enumerate(frames):
            apng.seek(k)
            assert apng.info["duration"] == pytest.approx(40.0)            # [ms]
            np.testing.assert_array_equal(np.asarray(apng.convert("RGBA" if channels == 4 else "RGB")), frame)
