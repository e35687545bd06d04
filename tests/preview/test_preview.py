"""warp_sim.preview: PNG files (decoded here with zlib and struct), the rasteriser's pixels, the USD and
Simulator sources, the HTML flipbook, and bad input."""
import math
import re
import struct
import zlib

import numpy as np
import pytest

import warp_sim as ws
from warp_sim import preview

W, H = 160, 120
RED, BLUE = (0.9, 0.1, 0.1), (0.1, 0.2, 0.9)


def decode_png(data: bytes) -> np.ndarray:
    """An 8-bit RGB or RGBA PNG as a (H, W, C) uint8 array; checks the signature, every chunk's CRC and IHDR."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "bad PNG signature"
    offset, chunks = 8, []
    while offset < len(data):
        length, kind = struct.unpack(">I4s", data[offset:offset + 8])
        body = data[offset + 8:offset + 8 + length]
        (crc,) = struct.unpack(">I", data[offset + 8 + length:offset + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, f"bad CRC in {kind!r}"
        chunks.append((kind, body))
        offset += 12 + length
    assert offset == len(data)
    assert chunks[0][0] == b"IHDR" and chunks[-1] == (b"IEND", b"")
    width, height, depth, colour, compression, filtering, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    assert (depth, compression, filtering, interlace) == (8, 0, 0, 0) and colour in (2, 6)
    channels = 3 if colour == 2 else 4
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(height, 1 + width * channels)
    out = rows[:, 1:].astype(np.int32)
    for y, kind in enumerate(rows[:, 0]):
        if kind == 1:                                   # Sub
            for x in range(channels, width * channels):
                out[y, x] = (out[y, x] + out[y, x - channels]) % 256
        elif kind == 2 and y:                           # Up
            out[y] = (out[y] + out[y - 1]) % 256
        else:
            assert kind in (0, 2), f"filter {kind} not decoded by this test"
    return out.astype(np.uint8).reshape(height, width, channels)


def front_camera():
    """Looking along -Z at (0, 1, 0) from (0, 1, 5): the horizon is the middle row, focal 0.5 H / tan 20 deg."""
    return preview.Camera(eye=(0.0, 1.0, 5.0), target=(0.0, 1.0, 0.0), fov=40.0)


def pixel_of(point, camera=None):
    """The (column, row) the camera above draws a point [m] in, by the pinhole model."""
    camera = camera or front_camera()
    eye, forward, right, up = camera.basis()
    d = np.asarray(point, dtype=np.float64) - eye
    focal = 0.5 * H / math.tan(math.radians(camera.fov) / 2.0)
    return 0.5 * W + focal * (d @ right) / (d @ forward), 0.5 * H - focal * (d @ up) / (d @ forward)


def is_red(image):
    rgb = image.astype(np.int32)
    return (rgb[..., 0] > 90) & (rgb[..., 0] > 2 * rgb[..., 1]) & (rgb[..., 0] > 2 * rgb[..., 2])


def ground_scene():
    scene = ws.Scene()
    scene.add_ground()
    return scene


# -- PNG ---------------------------------------------------------------------------------------------------------

def test_png_round_trip():
    rng = np.random.default_rng(1)
    image = rng.integers(0, 256, size=(7, 5, 3), dtype=np.uint8)
    data = preview.png_bytes(image)
    np.testing.assert_array_equal(decode_png(data), image)
    rgba = rng.integers(0, 256, size=(3, 4, 4), dtype=np.uint8)
    np.testing.assert_array_equal(decode_png(preview.png_bytes(rgba)), rgba)
    assert preview.PNGImage(image)._repr_png_() == data


def test_png_of_float_and_grey_images():
    grey = np.linspace(0.0, 1.0, 12).reshape(3, 4)
    decoded = decode_png(preview.png_bytes(grey))
    assert decoded.shape == (3, 4, 3)
    assert decoded[0, 0].tolist() == [0, 0, 0] and decoded[-1, -1].tolist() == [255, 255, 255]


@pytest.mark.parametrize("bad", [np.zeros((4, 4, 2), np.uint8), np.zeros((0, 4, 3), np.uint8), np.zeros(5),
                                 np.full((2, 2, 3), np.nan), np.zeros((2, 2, 3), dtype=np.int64)])
def test_png_rejects_bad_images(bad):
    with pytest.raises(ValueError):
        preview.png_bytes(bad)


# -- pixels ------------------------------------------------------------------------------------------------------

def test_particle_lights_its_pixel_and_the_ground_below_is_floor():
    scene = ground_scene()
    position = (0.5, 1.2, 0.0)
    scene.add_particles([position], radius=0.1, color=RED)
    sim = ws.Simulator(scene, integrator="euler", device="cpu")
    image = preview.render(sim, camera=front_camera(), width=W, height=H)[0]
    assert image.shape == (H, W, 3) and image.dtype == np.uint8
    red = is_red(image)
    column, row = pixel_of(position)
    rows, columns = np.nonzero(red)
    assert 20 < len(rows) < 40                   # a disc of radius focal * 0.1 / 5 = 3.3 px, its rim in shade
    assert abs(columns.mean() + 0.5 - column) < 1.0 and abs(rows.mean() + 0.5 - row) < 1.0
    assert red.sum() == red[int(row) - 4:int(row) + 5, int(column) - 4:int(column) + 5].sum()   # nowhere else
    # below the horizon (the middle row) lies the floor: grey, the same in each channel within a few levels
    floor = image[H - 5, 10].astype(int)
    tones = [np.round(255 * tone).astype(int) for tone in preview.raster._FLOOR]     # the checker's two, near: no fog
    assert min(np.abs(floor - tone).max() for tone in tones) <= 2
    # above it the sky: bluer than red
    sky = image[5, 10].astype(int)
    assert sky[2] > sky[0] + 10


def test_sphere_hides_what_is_behind_it():
    """A z-buffer: a near blue sphere covers a far red one at the same pixel."""
    near = preview.Snapshot(centres=np.array([[0.0, 1.0, 1.0], [0.0, 1.0, -1.0]]), radii=np.array([0.2, 0.4]),
                            sphere_colors=np.array([BLUE, RED]))
    image = preview.render(near, camera=front_camera(), width=W, height=H)[0]
    column, row = (int(v) for v in pixel_of((0.0, 1.0, 1.0)))
    assert image[row, column, 2] > 2 * image[row, column, 0]
    assert is_red(image).any()      # the far sphere is bigger than the near one's disc: its rim shows


def test_box_body_and_shadow():
    scene = ground_scene()
    scene.add_rigid_body(ws.Box((0.2, 0.2, 0.2)), position=(0.0, 0.8, 0.0), color=RED)
    sim = ws.Simulator(scene, integrator="euler", device="cpu")
    image = preview.render(sim, camera=front_camera(), width=W, height=H)[0]
    column, row = (int(v) for v in pixel_of((0.0, 0.8, 0.2)))
    assert is_red(image)[row, column]
    # the floor straight under the box (seen below it) is in its shadow: darker than the floor beside it
    under, beside = pixel_of((0.0, 0.0, 0.15)), pixel_of((1.0, 0.0, 0.15))
    shade = image[int(under[1]), int(under[0])].astype(int)
    floor = image[int(beside[1]), int(beside[0])].astype(int)
    assert not is_red(shade[None, None])[0, 0]
    assert shade.mean() < 0.8 * floor.mean()


def test_automatic_framing_keeps_everything_in_view():
    rng = np.random.default_rng(0)
    centres = rng.uniform((-2.0, 0.0, -1.0), (3.0, 2.0, 1.0), size=(40, 3))
    snap = preview.Snapshot(centres=centres, radii=np.full(40, 0.05), sphere_colors=np.tile(RED, (40, 1)))
    lo, hi = preview.Recording([snap]).bounds()
    for camera in (preview.Camera.framing(lo, hi, aspect=W / H),                       # the box's corners fit
                   preview.Camera.framing(lo, hi, aspect=W / H, points=centres, radii=snap.radii)):  # the points
        columns, rows = pixel_of(centres, camera)
        assert np.all((columns > 0) & (columns < W) & (rows > 0) & (rows < H))
    box = np.linalg.norm(np.subtract(preview.Camera.framing(lo, hi, aspect=W / H).eye, camera.target))
    assert np.linalg.norm(np.subtract(camera.eye, camera.target)) < box                # fitting the points: nearer
    image = preview.render(snap, width=W, height=H)[0]
    assert is_red(image).sum() > 40


# -- sources -----------------------------------------------------------------------------------------------------

def shapes_scene():
    scene = ground_scene()
    scene.add_particles([(0.6, 0.5, 0.0)], radius=0.05, color=RED, name="dot")
    chain = scene.add_particles([(-0.6 + 0.1 * k, 1.0, 0.0) for k in range(4)], pinned=[0], name="chain")
    scene.add_springs(np.stack([chain[:-1], chain[1:]], axis=1), stiffness=100.0)
    scene.add_rigid_body(ws.Capsule(0.05, 0.1), position=(0.0, 0.6, 0.0), color=BLUE, name="capsule")
    scene.add_rigid_body(ws.Cylinder(0.08, 0.04), position=(-0.3, 0.3, 0.0), name="drum")
    scene.add_collider(ws.Box((0.1, 0.05, 0.1)), position=(0.3, 0.05, 0.2), name="step")
    scene.add_cloth_grid(resolution=(4, 4), size=(0.3, 0.3), position=(0.0, 1.2, -0.3), mass=0.1,
                         stiffness=(10.0, 10.0, 1.0), damping=(0.01, 0.01, 0.001), name="patch")
    return scene


def test_usd_stage_renders_like_the_simulator(tmp_path):
    """The same frames from the Simulator (record) and from the stage its run() wrote agree pixel for pixel
    (but for a few rounding differences: the stage holds float32)."""
    direct = preview.record(ws.Simulator(shapes_scene(), integrator="rk4", device="cpu"), seconds=0.2, fps=20,
                            substeps=16)
    path = ws.Simulator(shapes_scene(), integrator="rk4", device="cpu").run(
        seconds=0.2, fps=20, substeps=16, usd=tmp_path / "shapes.usda", progress=False)
    staged = preview.read_usd(path)
    assert len(direct) == len(staged) == 4 and staged.fps == 20.0
    assert [s.time for s in staged.frames] == pytest.approx([0.0, 0.05, 0.1, 0.15])
    assert len(staged.planes) == 1 and len(direct.planes) == 1
    camera = preview.Camera.framing(*direct.bounds(), aspect=W / H)
    a = preview.render(direct, camera=camera, width=W, height=H)
    b = preview.render(staged, camera=camera, width=W, height=H)
    for x, y in zip(a, b):
        differ = np.abs(x.astype(int) - y.astype(int)).max(axis=2) > 12
        assert differ.mean() < 0.01
    assert is_red(a[-1]).any() and (a[-1][..., 2] > 2 * a[-1][..., 0]).any()   # the dot and the capsule


def test_any_usd_stage_of_gprims(tmp_path):
    """A stage not written by warp_sim: a sphere moving on a time-sampled translate, a static scaled cube, a
    cylinder along X; frames picked by time code."""
    from pxr import Gf, Usd, UsdGeom

    path = tmp_path / "hand.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(10)
    stage.SetTimeCodesPerSecond(10)
    ball = UsdGeom.Xform.Define(stage, "/Ball")
    move = ball.AddTranslateOp()
    for k in range(11):
        move.Set(Gf.Vec3d(0.1 * k, 1.0, 0.0), k)
    sphere = UsdGeom.Sphere.Define(stage, "/Ball/Geom")
    sphere.CreateRadiusAttr(0.25)
    sphere.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(*RED)])
    cube = UsdGeom.Cube.Define(stage, "/Block")
    cube.AddTranslateOp().Set(Gf.Vec3d(-1.0, 0.5, 0.0))
    cube.AddScaleOp().Set(Gf.Vec3f(0.5, 0.25, 0.5))
    cube.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(*BLUE)])
    UsdGeom.Cylinder.Define(stage, "/Drum").CreateAxisAttr(UsdGeom.Tokens.x)
    stage.GetRootLayer().Save()
    del stage

    recording = preview.read_usd(path, frames=[0, 5, 10])
    assert len(recording) == 3 and recording.fps == 10.0
    assert [s.time for s in recording.frames] == pytest.approx([0.0, 0.5, 1.0])
    np.testing.assert_allclose(recording.frames[2].centres, [[1.0, 1.0, 0.0]])
    np.testing.assert_allclose(recording.frames[2].radii, [0.25])
    static = recording.static.triangles.reshape(-1, 3)
    lo, hi = static.min(axis=0), static.max(axis=0)
    np.testing.assert_allclose(lo, [-1.5, -1.0, -1.0], atol=1e-6)     # the cube (size 2, scaled) and the drum
    np.testing.assert_allclose(hi, [1.0, 1.0, 1.0], atol=1e-6)       # (radius 1, height 2 along x)
    image = preview.render(recording, width=W, height=H)[1]
    assert is_red(image).any() and (image[..., 2] > 2 * image[..., 0]).any()


def test_record_calls_back_each_frame_and_snapshot_steps_nothing():
    sim = one_particle_sim()
    frames = []
    recording = preview.record(sim, seconds=0.3, fps=10, substeps=2, callback=lambda s, k: frames.append((k, s.time)))
    assert len(recording) == 3 and recording.fps == 10
    assert [k for k, _ in frames] == [0, 1, 2] and frames[-1][1] == pytest.approx(0.2)
    assert sim.step_count == 4
    one = preview.snapshot(sim)
    assert len(one) == 1 and sim.step_count == 4
    np.testing.assert_allclose(one.frames[0].centres, sim.state.particle_x.numpy(), atol=1e-6)


def test_flipbook_html_holds_every_frame():
    frames = [np.full((H, W, 3), k * 20, dtype=np.uint8) for k in range(5)]
    book = preview.flipbook(frames, fps=10)
    html = book._repr_html_()
    assert len(book) == 5 and html == book.html
    for k, png in enumerate(book.pngs):
        np.testing.assert_array_equal(decode_png(png), frames[k])
    apng = __import__("base64").b64decode(re.search(r'<img src="data:image/png;base64,([^"]+)"', html).group(1))
    assert apng == book.apng            # every frame in one animated PNG, decoded in tests/preview/test_apng.py
    assert html.count("data:image/png;base64,") == 2      # the animated PNG, and the player's prefix for its frames
    assert "<script" in html and '"range"' in html and "play" in html and "splitAPNG" in html


def test_animate_a_simulator_and_save(tmp_path):
    scene = ground_scene()
    scene.add_particles([(0.0, 1.0, 0.0)], velocities=[(0.5, 2.0, 0.0)], radius=0.05, color=RED)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    book = preview.animate(sim, seconds=0.5, fps=20, width=W, height=H)
    assert len(book) == 10 and book.fps == 20 and book.times[-1] == pytest.approx(0.45)
    assert sim.time == pytest.approx(0.45)
    page = book.save(tmp_path / "ball.html").read_text()
    assert page.startswith("<!DOCTYPE html>") and book.element_id in page


# -- bad input ---------------------------------------------------------------------------------------------------

def one_particle_sim():
    scene = ws.Scene()
    scene.add_particles([(0.0, 1.0, 0.0)])
    return ws.Simulator(scene, integrator="euler", device="cpu")


@pytest.mark.parametrize("call", [
    lambda: preview.flipbook([]),
    lambda: preview.flipbook(np.zeros((4, 4, 3), np.uint8)),
    lambda: preview.flipbook([np.zeros((4, 4, 3), np.uint8), np.zeros((5, 4, 3), np.uint8)]),
    lambda: preview.flipbook([b"not a png"]),
    lambda: preview.flipbook([np.zeros((4, 4, 3), np.uint8)], fps=0),
    lambda: preview.render(42),
    lambda: preview.render(one_particle_sim(), width=0),
    lambda: preview.render(one_particle_sim(), height=2.5),
    lambda: preview.render(one_particle_sim(), camera="front"),
    lambda: preview.render(one_particle_sim(), camera=dict(zoom=-1.0)),
    lambda: preview.render(one_particle_sim(), camera=dict(distance=3.0)),
    lambda: preview.Camera(eye=(0, 1, 0), target=(0, 1, 0)),
    lambda: preview.Camera(eye=(0, 5, 0), target=(0, 0, 0)),           # looking along up
    lambda: preview.Camera(fov=0.0),
    lambda: preview.read_usd("no/such/stage.usdc"),
    lambda: preview.record(one_particle_sim(), seconds=0.0),
    lambda: preview.record(one_particle_sim(), seconds=1.0, substeps=0),
    lambda: preview.record("not a simulator", seconds=1.0),
], ids=["empty", "array", "sizes", "not-png", "fps", "source", "width", "height", "camera", "zoom", "option",
         "eye-target",
        "up", "fov", "usd-path", "seconds", "substeps", "sim"])
def test_bad_input_is_a_value_error(call):
    with pytest.raises(ValueError):
        call()
