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
``(elementwise)`` for an array of any element type of the precision (all the kernel's arrays alike),
or, on a generic ``Any`` argument, the name of an argument block of ``warp_sim.kernels.blocks``
(``(Springs)``, ``(Bodies)``, ...): the struct of that name of the precision, ``blocks.of(scalar).Springs``.
An argument of a concrete struct type (``record: GuardRecord``) carries its struct's name as its tag::

    Args:
        springs: per spring its particles (p1, p2), ks, kd and L0 (Springs) [N/m]
        record: the first bad step and its lowest bad element's key (GuardRecord) [1]

The page's intro lists every block with its fields (from the struct classes) and their units (from the
bullet list of ``warp_sim.kernels.blocks``'s docstring, one ``- Name: ...`` item per block).
"""
from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path
from typing import Any

import generated_page  # tools/: beside this file (on sys.path when run as a script)

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "kernels.md"

#: the public topic modules, in the page's order (each has a non-empty ``__all__``)
TOPICS = ("integrate", "particles", "springs", "fields", "cloth", "rigid", "planes", "penalty", "guards")
#: the private modules (``__all__ = []``): for the simulator's own use
PRIVATE = ("contacts", "joints", "detection", "manifolds", "emitters", "implicit", "particle_shapes", "geometry",
           "precisions", "fused", "impulses", "contact_adjoint", "joint_frames",
           "joint_adjoint")
#: public modules without kernels: ``blocks``, the argument structs (its ``__all__``: of, fill)
HELPERS = ("blocks",)

KINDS = ("vec3", "quat", "mat33", "elementwise")
_ARG_LINE = re.compile(r"^    (?P<name>\w+): (?P<meaning>\S.*?) \[(?P<unit>[^\[\]]+)\]$")
_KIND_TAG = re.compile(r"^(?P<meaning>.*?)\s*\((?P<kind>[A-Za-z_]\w*)\)$")
_PRECISION_TYPES = {  # precision -> kind -> Warp type name
    "float32": {None: "float32", "vec3": "vec3f", "quat": "quatf", "mat33": "mat33f"},
    "float64": {None: "float64", "vec3": "vec3d", "quat": "quatd", "mat33": "mat33d"},
}


def _blocks_module():
    return importlib.import_module("warp_sim.kernels.blocks")


def block_names() -> tuple[str, ...]:
    """The argument blocks of ``warp_sim.kernels.blocks``, in its order (the same in both precisions)."""
    import warp as wp

    blocks = _blocks_module()
    names = tuple(vars(blocks.of(wp.float32)))
    if tuple(vars(blocks.of(wp.float64))) != names:
        raise ValueError("warp_sim.kernels.blocks: of(wp.float32) and of(wp.float64) define different blocks")
    return names


def block_type(name: str, precision: str):
    """The struct type of block ``name`` in ``precision`` ("float32" or "float64")."""
    import warp as wp

    return getattr(_blocks_module().of(getattr(wp, precision)), name)


def _is_struct(t) -> bool:
    import warp as wp

    return wp.types.type_is_struct(t)


def _struct_name(t) -> str:
    return t.cls.__name__


def _element_label(t, precision: str | None) -> str:
    """A field's element type as the page shows it: scalar, vec3, quat or mat33 for the precision's own types
    (``precision`` given: a block), else the Warp type's name (int32, vec2i, ...)."""
    if precision is not None:
        for kind, name in _PRECISION_TYPES[precision].items():
            if _type_name(t) == name:
                return kind or "scalar"
    return _type_name(t)


def struct_fields(t, precision: str | None = None) -> list[tuple[str, str, bool]]:
    """(name, element type label, is an array) of each field of the struct type ``t``, in declaration order
    (``StructType.vars``: name -> Var, its ``type`` the field's Warp type)."""
    import warp as wp

    fields = []
    for name, var in t.vars.items():
        is_array = isinstance(var.type, wp.array)
        element = var.type.dtype if is_array else var.type
        fields.append((name, _element_label(element, precision), is_array))
    return fields


def describe_fields(fields: list[tuple[str, str, bool]]) -> str:
    """"pairs (vec2i array), stiffness, damping, rest_length (scalar arrays)": runs of fields of one type
    share their type's label."""
    groups: list[tuple[list[str], str, bool]] = []
    for name, label, is_array in fields:
        if groups and groups[-1][1:] == (label, is_array):
            groups[-1][0].append(name)
        else:
            groups.append(([name], label, is_array))
    parts = []
    for names, label, is_array in groups:
        if is_array:
            label = f"{label} array" + ("s" if len(names) > 1 else "")
        elif len(names) > 1:
            label = f"{label} each"
        parts.append(f"{', '.join(names)} ({label})")
    return ", ".join(parts)


def block_fields(name: str) -> list[tuple[str, str, bool]]:
    """The fields of block ``name`` with their kinds; ValueError where its two precisions differ in them."""
    fields = struct_fields(block_type(name, "float32"), "float32")
    if struct_fields(block_type(name, "float64"), "float64") != fields:
        raise ValueError(f"warp_sim.kernels.blocks.{name}: its float32 and float64 structs differ in their fields")
    return fields


def block_docs() -> dict[str, str]:
    """{block name: its item of the bullet list in ``warp_sim.kernels.blocks``'s docstring, the fields' meanings
    and units}. ValueError where a block has no item, an item names no block, or a field is not mentioned."""
    items: dict[str, str] = {}
    current = None
    for line in inspect.cleandoc(_blocks_module().__doc__ or "").splitlines():
        match = re.match(r"^- (\w+)(?: \((?P<note>[^()]*)\))?: (?P<text>.*)$", line)
        if match:
            current = match[1]
            items[current] = (f"{match['note']}: " if match["note"] else "") + match["text"].strip()
        elif current is not None and line.startswith("  ") and line.strip():
            items[current] += " " + line.strip()
        else:
            current = None
    names = block_names()
    if set(items) != set(names):
        raise ValueError(f"warp_sim.kernels.blocks: blocks {sorted(set(items) ^ set(names))} need exactly one "
                         "'- Name: fields and units' item in the module's docstring")
    for name in names:
        for field, _, _ in block_fields(name):
            if not re.search(rf"(?<![\w.]){re.escape(field)}(?!\w)", items[name]):
                raise ValueError(f"warp_sim.kernels.blocks: the docstring's item for {name} does not mention "
                                 f"its field {field}")
    return {name: items[name] for name in names}


class Argument:
    """One kernel argument: its name, Warp type, kind of generic element (None: the scalar; a block's name: that
    block's struct), meaning and unit."""

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

    @property
    def is_block(self) -> bool:
        """A generic argument tagged with a block's name."""
        return self.generic and self.kind is not None and self.kind not in KINDS

    def dtype(self) -> str:
        """The argument's type as the page shows it."""
        if not self.generic:
            if self.is_array:
                return f"array of {_type_name(self.type.dtype)}"
            if _is_struct(self.type):
                module = self.type.cls.__module__.removeprefix("warp_sim.")
                return f"`{module}` {_struct_name(self.type)} struct: {describe_fields(struct_fields(self.type))}"
            return _type_name(self.type)
        if self.is_block:
            return (f"`kernels.blocks` [{self.kind}](#argument-blocks) struct of the precision: "
                    f"{describe_fields(block_fields(self.kind))}")
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
        if self.is_block:
            return block_type(self.kind, precision)
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

    A trailing ``(tag)`` of the meaning is the kind when it is one of KINDS, a block's name, or the name of one
    of the kernel's concrete struct argument types; any other parenthesis stays part of the meaning.

    Raises ValueError for a kernel without a docstring or ``Args:`` block, or an argument line
    not of the form ``name: meaning [unit]``."""
    doc = kernel.func.__doc__
    if not doc:
        raise ValueError(f"kernel {kernel.key} has no docstring")
    lines = inspect.cleandoc(doc).splitlines()
    if "Args:" not in lines:
        raise ValueError(f"kernel {kernel.key}: its docstring has no 'Args:' block")
    start = lines.index("Args:")
    tags = set(KINDS) | set(block_names())
    tags |= {_struct_name(arg.type) for arg in kernel.adj.args if _is_struct(arg.type)}
    entries = []
    end = start + 1
    while end < len(lines) and lines[end].startswith("    "):
        match = _ARG_LINE.match(lines[end])
        if match is None:
            raise ValueError(f"kernel {kernel.key}: argument line {lines[end].strip()!r} is not "
                             "'name: meaning [unit]'")
        meaning, kind = match["meaning"], None
        tagged = _KIND_TAG.match(meaning)
        if tagged is not None and tagged["kind"] in tags:
            meaning, kind = tagged["meaning"], tagged["kind"]
        entries.append((match["name"], kind, meaning, match["unit"]))
        end += 1
    prose = "\n".join(lines[:start] + lines[end:]).strip()
    return prose, entries


def kernel_arguments(kernel) -> list[Argument]:
    """The documented arguments of a public kernel, in launch order.

    Raises ValueError where the docstring's argument lines do not match the signature one for one,
    a kind tag is on an argument that is not generic (but for a concrete struct's own name), a block tag is on
    an array, or a concrete struct argument lacks its struct's name as its tag."""
    _, entries = split_docstring(kernel)
    names = [arg.label for arg in kernel.adj.args]
    documented = [entry[0] for entry in entries]
    if documented != names:
        raise ValueError(f"kernel {kernel.key}: documented arguments {documented} differ from its "
                         f"signature {names} (one line per argument, in order)")
    arguments = []
    for arg, (name, kind, meaning, unit) in zip(kernel.adj.args, entries):
        argument = Argument(name, arg.type, kind, meaning, unit)
        if _is_struct(arg.type):
            if kind != _struct_name(arg.type):
                raise ValueError(f"kernel {kernel.key}: argument {name} is a {_struct_name(arg.type)} struct: its "
                                 f"line must end with ({_struct_name(arg.type)}) before the unit")
        elif kind is not None and not argument.generic:
            raise ValueError(f"kernel {kernel.key}: argument {name} has the concrete type "
                             f"{argument.dtype()}: no ({kind}) tag")
        if kind == "elementwise" and not argument.is_array:
            raise ValueError(f"kernel {kernel.key}: (elementwise) is for array arguments, not {name}")
        if argument.is_block and argument.is_array:
            raise ValueError(f"kernel {kernel.key}: ({kind}) is a block, a struct argument (Any), not an array: {name}")
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
    listed = set(TOPICS) | set(PRIVATE) | set(HELPERS)
    if found != listed:
        raise ValueError(f"warp_sim.kernels modules {sorted(found ^ listed)}: list each in TOPICS (public), "
                         "PRIVATE or HELPERS of tools/kernel_docs.py, and only modules that exist")
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
from warp_sim.kernels import blocks, springs

B = blocks.of(wp.float64)                     # the argument blocks of one precision
springs_block = blocks.fill(B.Springs, pairs=pairs, stiffness=stiffness, damping=damping,
                            rest_length=rest_length)
wp.launch(springs.spring_forces, dim=spring_count, inputs=[x, v, springs_block, force], device="cpu")
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

BLOCKS_INTRO = """\
## Argument blocks

Arrays that go together (a spring's particles and constants, a body's state, a plane's normal and
offset) are passed as one struct argument, a *block*, defined per precision in
`warp_sim.kernels.blocks`: `blocks.of(wp.float32)` and `blocks.of(wp.float64)` return the block types
of that precision, and `blocks.fill(BlockType, **arrays)` builds one from your arrays, one keyword per
field:

```python
import warp as wp
from warp_sim.kernels import blocks

B = blocks.of(wp.float64)
springs = blocks.fill(B.Springs, pairs=wp.array(pairs, dtype=wp.vec2i),
                      stiffness=wp.array(ks, dtype=wp.float64), damping=wp.array(kd, dtype=wp.float64),
                      rest_length=wp.array(rest, dtype=wp.float64))
```

Give every field, each an array of the block's precision (the float64 block's vec3 fields are `vec3d`
arrays, and so on) on the launch's device; a field documented as possibly empty takes
`wp.empty(0, dtype=...)`. A kernel's table names the block an argument takes, with the unit of the main
quantity the kernel reads or writes there; the blocks, their fields in order, and the fields' meanings and
units:
"""


def render() -> str:
    """The text of docs/kernels.md for the kernels as they are now."""
    import warp as wp

    _check_modules()
    lines = [INTRO, BLOCKS_INTRO]
    used_by: dict[str, list[str]] = {name: [] for name in block_names()}
    structs: dict[str, tuple[str, Any]] = {}   # concrete struct name -> (module, type)
    for topic in TOPICS:
        for kernel in public_kernels(topic):
            for argument in kernel_arguments(kernel):
                if argument.is_block and f"{topic}.{kernel.key}" not in used_by[argument.kind]:
                    used_by[argument.kind].append(f"{topic}.{kernel.key}")
                elif not argument.generic and _is_struct(argument.type):
                    structs[_struct_name(argument.type)] = (argument.type.cls.__module__, argument.type)
    lines += ["| block | fields (element types) | meaning and units | taken by |", "| --- | --- | --- | --- |"]
    for name, text in block_docs().items():
        users = ", ".join(f"[`{k}`](#{k.replace('.', '')})" for k in used_by[name]) or "private kernels only"
        lines.append(f"| `{name}` | {_cell(describe_fields(block_fields(name)))} | {_cell(text)} | {users} |")
    lines.append("")
    for name, (module, t) in sorted(structs.items()):
        doc = " ".join(inspect.cleandoc(t.cls.__doc__ or "").split())
        fields = struct_fields(t)
        keywords = ", ".join(f"{field}=..." for field, _, _ in fields)
        lines += [f"`{module}.{name}`, a struct argument that is the same in both precisions, has the fields "
                  f"{describe_fields(fields)}. {doc} Build it as a block: "
                  f"`blocks.fill({module.rsplit('.', 1)[-1]}.{name}, {keywords})`.", ""]
    lines += ["## Topics", ""]
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
    return generated_page.diff(path, render())


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    import warp as wp

    wp.config.quiet = True
    return generated_page.main(argv, __doc__.splitlines()[0], ROOT, DOCS, render, "kernel_docs.py")


if __name__ == "__main__":
    sys.exit(main())
