"""Previews without a GPU or a display: a small numpy rasteriser, PNG frames and an HTML flipbook.

Two sources: a :class:`~warp_sim.Simulator` run frame by frame (:func:`record`), or a USD stage
written by ``Simulator.run(usd=...)`` (:func:`read_usd`; any stage of Points, Meshes, BasisCurves,
Spheres, Cubes, Capsules and Cylinders under Xforms will do). Either becomes a :class:`Recording`
(world-space geometry per frame), which :func:`render` draws with a fixed perspective camera:

* particles and spheres as shaded discs, at least ``min_point_px`` pixels in radius;
* cloth, soft bodies, boxes, capsules, cylinders and meshes as flat-shaded triangles (z-buffer);
* springs and curves as one-pixel lines;
* planes as checkered floors fading into the sky, with straight-down blob shadows on floors.

:func:`flipbook` wraps the frames in a self-contained HTML snippet whose :class:`Flipbook` shows itself inline in
Jupyter: an animated PNG (:func:`apng_bytes`, lossless, looping) in an ``<img>``, which plays with no script at all
(an untrusted notebook, GitHub's and other static notebook views), and a player (play and pause, a slider, each
frame's time) that script adds where it runs (a trusted notebook, nbviewer, a saved page). ``book.save("clip.png")``
writes the animated PNG alone, ``book.save("clip.html")`` a page. :func:`animate` does all three::

    import warp_sim as ws
    from warp_sim import preview

    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    preview.animate(sim, seconds=2.0, fps=30)                    # runs the simulator (as run()), then shows it
    preview.animate("out/scene.usdc", camera=dict(azimuth=60))   # or a written stage

The camera: ``camera=None`` looks at the centre of the box around everything in every frame (planes
aside) from azimuth 35 and elevation 20 degrees, as near as it can with all of it in view; a dict
of :meth:`Camera.framing` options (``azimuth``, ``elevation``, ``fov``, ``zoom``) changes those; a
:class:`Camera` (eye, target, up, fov) fixes it.
The sky and the floors do not change with the frame and are drawn once per render.

Units: positions and sizes in metres, angles in degrees, times in seconds, image sizes in pixels.
PNG and APNG files are written with zlib and struct only. Speed: 64 frames of 320 x 240 of a few dozen
bodies and particles and a 20 x 20 cloth take about a second to draw and encode on two CPU cores.
"""
from __future__ import annotations

from .frames import Recording, Snapshot, read_usd, record, snapshot
from .output import Flipbook, PNGImage, apng_bytes, flipbook, png_bytes
from .raster import Camera, _recording, render

__all__ = ["Camera", "Snapshot", "Recording", "snapshot", "record", "read_usd", "render", "png_bytes", "PNGImage",
           "apng_bytes", "Flipbook", "flipbook", "animate"]



def animate(source, camera=None, width: int = 320, height: int = 240, seconds: float | None = None,
            fps: float | None = None, substeps="auto", frames=None, min_point_px: float = 1.0,
            title: str = "warp_sim preview") -> Flipbook:
    """Render ``source`` (see :func:`render`) and return its Flipbook, played at ``fps`` (default: the
    recording's frame rate; for a Simulator, also the rate it is recorded at, 30 when not given)."""
    recording = _recording(source, seconds, 30.0 if fps is None else fps, substeps, frames)
    images = render(recording, camera=camera, width=width, height=height, min_point_px=min_point_px)
    rate = recording.fps if fps is None else fps
    return flipbook(images, fps=rate, times=[s.time for s in recording.frames], title=title)
