"""A scene's revision: a count of its changes, so that a Simulator built from it can refuse it once it changed.

A Simulator reads its Scene once, into the device's Model and State; particles, bodies or springs added after that,
or a gravity set, would be ignored silently. So every ``add_*`` method (``changes``) and every attribute set bumps
``Scene.revision``; the Simulator records it when it is built and its ``step()``, ``frames()`` and ``run()`` refuse
a scene whose revision moved since (``require``): one integer comparison.
"""
from __future__ import annotations

import functools

from ..util import checks


class Revised:
    """A description whose attribute sets and ``changes`` methods count in ``revision``."""

    def __setattr__(self, name: str, value) -> None:
        object.__setattr__(self, name, value)
        if name != "_revision":
            object.__setattr__(self, "_revision", self.__dict__.get("_revision", 0) + 1)

    @property
    def revision(self) -> int:
        """How many changes (add_* calls and attribute sets) the scene has had; a Simulator records it."""
        return self.__dict__.get("_revision", 0)

    def require(self, revision: int) -> None:
        """Raise ValueError unless the scene is still at ``revision`` (the one its Simulator was built from)."""
        if self.__dict__.get("_revision", 0) != revision:
            raise checks.fail("scene", self, "the scene changed after its Simulator was built (an add_* call or an "
                                             "attribute set), and a Simulator reads its scene once; build a new one "
                                             "for the changed scene: ws.Simulator(scene)")


def changes(method):
    """Mark a method that changes the scene: every call bumps its revision (one that fails too, as it may have added
    part of what it was given)."""
    @functools.wraps(method)
    def changing(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        finally:
            self._revision = self.revision + 1
    return changing
