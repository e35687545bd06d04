"""Write docs/kernels.md, the reference of the public Warp kernels of ``warp_sim.kernels``.

    python tools/kernel_docs.py            # rewrite docs/kernels.md
    python tools/kernel_docs.py --check    # exit 1, printing a diff, if docs/kernels.md is out of date

The public kernels of a topic module are the names in its ``__all__``; every other module of
``warp_sim.kernels`` has ``__all__ = []`` and is listed as private. For each public kernel the page
shows its arguments in launch order, from ``kernel.adj.args`` (names and Warp types), with the
meaning and unit of each from the kernel's docstring, whose ``Args:`` block has one line per
argument::

    Args:
        x: particle positions (vec3) [m]
        h: the step [s]

A generic argument (``Any`` or ``wp.array(dtype=Any)``) takes the precision's scalar unless its
line ends, before the unit, with a kind tag: ``(vec3)``, ``(quat)``, ``(mat33)``, or
``(elementwise)`` for an array of any element type of the precision (all the kernel's arrays alike).
"""
from __future__ import annotations

import argparse
import difflib
import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "kernels.md"

#: the public topic modules, in the page's order (each has a non-empty ``__all__``)
TOPICS = ("integrate", "particles", "springs", "fields", "cloth", "rigid", "planes", "penalty", "guards")
#: the private modules (``__all__ = []``): for the simulator's own use
PRIVATE = ("contacts", "detection", "emitters", "implicit", "particle_shapes", "geometry", "precisions")

KINDS = ("vec3", "quat", "mat33", "elementwise")
_ARG_LINE = re.compile(r"^    (?P<name>\w+): (?P<meaning>\S.*?) \[(?P<unit>[^\[\]]+)\]$")
_KIND_TAG = re.compile(r"^(?P<meaning>.*?)\s*\((?P<kind>" + "|".join(KINDS) + r")\)$")
_PRECISION_TYPES = {  # precision -> kind -> Warp type name
    "float32": {None: "float32", "vec3": "vec3f", "quat": "quatf", "mat33": "mat33f"},
    "float64": {None: "float64", "vec3": "vec3d", "quat": "quatd", "mat33": "mat33d"},
}


class Argument:
    """One kernel argument: its name, Warp type, kind of generic element (None: the scalar), meaning and unit."""

    def __init__(self, name: str, type, kind: str | None, meaning: str, unit: str):
        self.name, self.type, self.kind, self.meaning, self.unit = name, type, kind, meaning, unit

    @property
    def is_array(self) -> bool:
        import warp as wp

        return isinstance(self.type, wp.array)

    @property
    def generic(self) -> bool:
        element = self.type.dtype if self.is_array else self.type
        return element is Any

    def dtype(self) -> str:
        """The argument's type as the page shows it."""
        if not self.generic:
            if self.is_array:
                return f"array of {_type_name(self.type.dtype)}"
            return _type_name(self.type)
        if self.kind == "elementwise":
            return ("array of scalar, vec3, quat or mat33 of the precision "
                    "(one element type for all the kernel's arrays)")
        what = self.kind or "scalar"
        names = " or ".join(_PRECISION_TYPES[p][self.kind] for p in _PRECISION_TYPES)
        if self.is_array:
            return f"array of {what} of the precision ({names})"
        if self.kind is None:
            return "float32 or float64 (the precision)"
        return f"{names} ({what} of the precision)"

    def concrete(self, precision: str):
        """The Warp type of this argument in ``precision`` ("float32" or "float64"); for ``elementwise``
        arrays, the scalar's."""
        import warp as wp

        if not self.generic:
            return self.type
        kind = None if self.kind == "elementwise" else self.kind
        element = getattr(wp, _PRECISION_TYPES[precision][kind])
        return wp.array(dtype=element) if self.is_array else element


def _type_name(t) -> str:
    if t is int:
        return "int32 (a Python int)"
    if t is float:
        return "float32 (a Python float)"
    return getattr(t, "__name__", str(t))


def split_docstring(kernel) -> tuple[str, list[tuple[str, str | None, str, str]]]:
    """(the prose of a kernel's docstring, its ``Args:`` lines as (name, kind, meaning, unit)).

    Raises ValueError for a kernel without a docstring or ``Args:`` block, or an argument line
    not of the form ``name: meaning [unit]``."""
    doc = kernel.func.__doc__
    if not doc:
        raise ValueError(f"kernel {kernel.key} has no docstring")
    lines = inspect.cleandoc(doc).splitlines()
    if "Args:" not in lines:
        raise ValueError(f"kernel {kernel.key}: its docstring has no 'Args:' block")
    start = lines.index("Args:")
    entries = []
    end = start + 1
    while end < len(lines) and lines[end].startswith("    "):
        match = _ARG_LINE.match(lines[end])
        if match is None:
            raise ValueError(f"kernel {kernel.key}: argument line {lines[end].strip()!r} is not "
                             "'name: meaning [unit]'")
        meaning, kind = match["meaning"], None
        tagged = _KIND_TAG.match(meaning)
        if tagged is not None:
            meaning, kind = tagged["meaning"], tagged["kind"]
        entries.append((match["name"], kind, meaning, match["unit"]))
        end += 1
    prose = "\n".join(lines[:start] + lines[end:]).strip()
    return prose, entries


def kernel_arguments(kernel) -> list[Argument]:
    """The documented arguments of a public kernel, in launch order.

    Raises ValueError where the docstring's argument lines do not match the signature one for one,
    or a kind tag is on an argument that is not generic."""
    _, entries = split_docstring(kernel)
    names = [arg.label for arg in kernel.adj.args]
    documented = [entry[0] for entry in entries]
    if documented != names:
        raise ValueError(f"kernel {kernel.key}: documented arguments {documented} differ from its "
                         f"signature {names} (one line per argument, in order)")
    arguments = []
    for arg, (name, kind, meaning, unit) in zip(kernel.adj.args, entries):
        argument = Argument(name, arg.type, kind, meaning, unit)
        if kind is not None and not argument.generic:
            raise ValueError(f"kernel {kernel.key}: argument {name} has the concrete type "
                             f"{argument.dtype()}: no ({kind}) tag")
        if kind == "elementwise" and not argument.is_array:
            raise ValueError(f"kernel {kernel.key}: (elementwise) is for array arguments, not {name}")
        arguments.append(argument)
    return arguments


def concrete_types(kernel, precision: str) -> dict:
    """{argument name: Warp type} of a public kernel in ``precision``, as its documentation says."""
    return {argument.name: argument.concrete(precision) for argument in kernel_arguments(kernel)}


def topic_module(topic: str):
    return importlib.import_module(f"warp_sim.kernels.{topic}")


def public_kernels(topic: str) -> list:
    """The kernels named in a topic module's ``__all__``, in that order."""
    module = topic_module(topic)
    return [getattr(module, name) for name in module.__all__]


def _check_modules() -> None:
    import warp_sim.kernels as package

    found = {info.name for info in pkgutil.iter_modules(package.__path__)}
    listed = set(TOPICS) | set(PRIVATE)
    if found != listed:
        raise ValueError(f"warp_sim.kernels modules {sorted(found ^ listed)}: list each in TOPICS (public) "
                         "or PRIVATE of tools/kernel_docs.py, and only modules that exist")
    for topic in TOPICS:
        if not getattr(topic_module(topic), "__all__", None):
            raise ValueError(f"warp_sim.kernels.{topic} is a public topic but has no public kernels in __all__")
    for name in PRIVATE:
        if getattr(topic_module(name), "__all__", None) != []:
            raise ValueError(f"warp_sim.kernels.{name} is private: it must have __all__ = []")


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _markdown_prose(text: str) -> list[str]:
    """Docstring prose as markdown: wrapped lines of a paragraph joined, indented lines as code blocks."""
    out: list[str] = []
    paragraph: list[str] = []
    code: list[str] = []

    def flush():
        if paragraph:
            out.extend([" ".join(paragraph), ""])
            paragraph.clear()
        if code:
            out.extend(["```text", *code, "```", ""])
            code.clear()

    for line in text.splitlines():
        if not line.strip():
            flush()
        elif line.startswith(" "):
            if paragraph:
                out.extend([" ".join(paragraph), ""])
                paragraph.clear()
            code.append(line[4:] if line.startswith("    ") else line.strip())
        else:
            if code:
                flush()
            paragraph.append(line.strip())
    flush()
    return out


def _first_line(module) -> str:
    return inspect.cleandoc(module.__doc__ or "").split("\n\n")[0].replace("\n", " ").strip()


def _module_prose(module) -> str:
    """A topic module's docstring without its first line and its "Public (...)" and "Private:" paragraphs
    (the page lists those itself)."""
    paragraphs = inspect.cleandoc(module.__doc__ or "").split("\n\n")[1:]
    return "\n\n".join(p for p in paragraphs if not p.startswith(("Public (", "Private:")))


INTRO = """\
# Public Warp kernels

<!-- Generated by tools/kernel_docs.py from the kernels' signatures and docstrings: do not edit.
     After changing a public kernel run `python tools/kernel_docs.py`; `--check` tells whether
     this file is up to date (tests/kernels/test_public_kernels.py runs it). -->

The kernels below, the names in each `warp_sim.kernels.<topic>` module's `__all__`, are public: launch them
on your own Warp arrays, outside any `Simulator`. Every other kernel (and every module listed under
[Private modules](#private-modules)) is for the simulator's own use: its arguments may change between releases.

## Launching

```python
import warp as wp
from warp_sim.kernels import springs

wp.launch(springs.spring_forces, dim=spring_count,
          inputs=[x, v, pairs, stiffness, damping, rest_length, force], device="cpu")
```

`inputs` go in the order of the kernel's table; `dim` is the number of threads, one per element
(particle, spring, triangle, body, ...: each kernel says which); `device` is the device that holds the
arrays ("cpu", "cuda:0"). Accumulators ("added to") are atomic adds: zero them first
(`force.zero_()`) for the kernel's contribution alone. An argument documented as "or an empty array"
may be `wp.empty(0, dtype=...)` of its type.

**Precision.** Every kernel is generic over the precision: pass all float arrays and scalars of one
precision, either float32 with vec3f, quatf and mat33f, or float64 with vec3d, quatd and mat33d. Pass
scalars and vectors as typed values (`wp.float64(1e-3)`, `wp.vec3d(0.0, -9.81, 0.0)`) so that they
match the arrays. Integer arguments (`int32`, `vec2i`, `vec3i`) are the same in both precisions.
Quaternions are (x, y, z, w), Warp's layout. Units are SI; `[1]` marks a dimensionless value.
"""


def render() -> str:
    """The text of docs/kernels.md for the kernels as they are now."""
    import warp as wp

    _check_modules()
    lines = [INTRO, "## Topics", ""]
    for topic in TOPICS:
        names = ", ".join(f"[`{name}`](#{topic}{name})" for name in topic_module(topic).__all__)
        lines.append(f"- [`{topic}`](#{topic}): {names}")
    lines.append("")
    for topic in TOPICS:
        module = topic_module(topic)
        lines += [f"## {topic}", "", f"`warp_sim.kernels.{topic}`: {_first_line(module)}", ""]
        lines += _markdown_prose(_module_prose(module))
        for kernel in public_kernels(topic):
            prose, _ = split_docstring(kernel)
            arguments = kernel_arguments(kernel)
            lines += [f"### {topic}.{kernel.key}", "",
                      f"`{kernel.key}({', '.join(a.name for a in arguments)})`", ""]
            lines += _markdown_prose(prose)
            lines += ["| argument | dtype | meaning [unit] |", "| --- | --- | --- |"]
            for a in arguments:
                lines.append(f"| `{a.name}` | {_cell(a.dtype())} | {_cell(a.meaning)} [{_cell(a.unit)}] |")
            lines.append("")
        private = [name for name, value in vars(module).items()
                   if isinstance(value, wp.Kernel) and name not in module.__all__]
        if private:
            lines += [f"Private kernels of `{topic}` (for the simulator's own use, their arguments may change "
                      f"between releases): {', '.join(f'`{name}`' for name in private)}.", ""]
    lines += ["## Private modules", "",
              "These modules have `__all__ = []`: their kernels and functions are for the simulator's own use, "
              "and their arguments may change between releases.", ""]
    for name in PRIVATE:
        lines.append(f"- `warp_sim.kernels.{name}`: {_first_line(topic_module(name))}")
    lines.append("")
    return "\n".join(lines)


def check(path: Path = DOCS) -> list[str]:
    """The unified diff from ``path`` to the page as generated now: empty when it is up to date."""
    current = path.read_text(encoding="utf-8") if path.exists() else ""
    expected = render()
    return list(difflib.unified_diff(current.splitlines(keepends=True), expected.splitlines(keepends=True),
                                     fromfile=str(path), tofile="generated"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if docs/kernels.md is out of date")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import warp as wp

    wp.config.quiet = True
    if args.check:
        diff = check()
        if diff:
            sys.stdout.writelines(diff)
            print(f"\n{DOCS.relative_to(ROOT)} is out of date: run python tools/kernel_docs.py")
            return 1
        print(f"{DOCS.relative_to(ROOT)} is up to date")
        return 0
    DOCS.parent.mkdir(parents=True, exist_ok=True)
    DOCS.write_text(render(), encoding="utf-8")
    print(f"wrote {DOCS.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
