"""The architecture page's diagram, drawn from the import-linter contracts in pyproject.toml (the ones
``lint-imports`` enforces), so the picture cannot drift from the rules: the package's layers top to bottom, each
captioned by the first sentence of its package's docstring; inside a layer, the layers of each container (a
family's device > transport > sim > protocol); containers that must not import each other side by side.

A plain SVG written at build time: it needs no Graphviz binary and no JavaScript, and builds offline with ``-W``."""

from __future__ import annotations

import ast
import re
import textwrap
import tomllib
from dataclasses import dataclass, field
from html import escape
from pathlib import Path

WIDTH = 760
MARGIN = 16
LINE = 16  # px per caption line
CHAR = 6.6  # px per character of the 12 px caption font, on average: where captions wrap
ARROW = 22  # the gap between two layers, where the "may import" arrow goes
FILL = ("#eef4fb", "#f6f8fa")  # a layer's, a container's inner layer's
INK, EDGE, ARROW_INK = "#1d2330", "#57606a", "#0969da"


@dataclass
class Stack:
    """Layers top to bottom (``layers`` contract); ``inner``: containers drawn inside a layer, by its name;
    ``apart``: the containers of an ``independence`` contract, by the layer holding them."""

    layers: list[str]
    inner: dict[str, list[tuple[str, list[str]]]] = field(default_factory=dict)
    apart: dict[str, list[str]] = field(default_factory=dict)
    also: list[str] = field(default_factory=list)  # the other contracts' names (no cycles…): said under the picture


def read_contracts(pyproject: Path) -> Stack:
    """The top-level ``layers`` contract (no containers), the container ones placed in the layer above them."""
    contracts = tomllib.loads(pyproject.read_text(encoding="utf-8"))["tool"]["importlinter"]["contracts"]
    top = next(c for c in contracts if c["type"] == "layers" and not c.get("containers"))
    stack = Stack(list(top["layers"]))
    stack.also = [c["name"] for c in contracts if c["type"] not in ("layers", "independence")]
    for contract in contracts:
        if contract["type"] == "layers" and contract.get("containers"):
            for container in contract["containers"]:
                stack.inner.setdefault(_holder(stack, container), []).append((container, list(contract["layers"])))
        elif contract["type"] == "independence":
            stack.apart[_holder(stack, contract["modules"][0])] = list(contract["modules"])
    return stack


def _holder(stack: Stack, module: str) -> str:
    """The top-level layer that ``module`` belongs to."""
    return next(layer for layer in stack.layers if module == layer or module.startswith(layer + "."))


def first_sentence(package: str, root: Path) -> str:
    """The first sentence of ``package``'s docstring (``hil.io`` → hil/io/__init__.py), its reST roles plain."""
    source = root.joinpath(*package.split("."), "__init__.py")
    doc = ast.get_docstring(ast.parse(source.read_text(encoding="utf-8"))) or ""
    text = re.sub(r":\w+:`~?([^`]+)`", r"\1", " ".join(doc.split("\n\n")[0].split())).replace("``", "")
    return re.split(r"(?<=[.;])\s", text, maxsplit=1)[0].rstrip(".;")


def _text(x: float, y: float, text: str, *, size: int = 12, weight: str = "normal", anchor: str = "start") -> str:
    return (f'<text x="{x:.0f}" y="{y:.0f}" font-size="{size}" font-weight="{weight}" text-anchor="{anchor}" '
            f'fill="{INK}">{escape(text)}</text>')


def _box(x: float, y: float, w: float, h: float, fill: str) -> str:
    return f'<rect x="{x:.0f}" y="{y:.0f}" width="{w:.0f}" height="{h:.0f}" rx="6" fill="{fill}" stroke="{EDGE}"/>'


def _arrow(x: float, y0: float, y1: float) -> str:
    """Downwards: the layer above may import the one below."""
    return (f'<line x1="{x:.0f}" y1="{y0:.0f}" x2="{x:.0f}" y2="{y1 - 5:.0f}" stroke="{ARROW_INK}" stroke-width="1.5"/>'
            f'<path d="M{x - 4:.0f},{y1 - 6:.0f} L{x + 4:.0f},{y1 - 6:.0f} L{x:.0f},{y1:.0f} z" fill="{ARROW_INK}"/>')


def _column(x: float, y: float, w: float, container: str, layers: list[str]) -> tuple[list[str], float]:
    """One container's layers, top to bottom, in a column ``w`` wide; the shapes and the height used."""
    parts = [_text(x + w / 2, y + 14, container.rsplit(".", 1)[-1] + "/", weight="bold", anchor="middle")]
    y += 22
    for i, layer in enumerate(layers):
        if i:
            parts.append(_arrow(x + w / 2, y - 10, y))
        parts += [_box(x, y, w, 24, FILL[1]), _text(x + w / 2, y + 16, layer, anchor="middle")]
        y += 24 + 10
    return parts, 22 + len(layers) * 34 - 10


def _layer(stack: Stack, layer: str, y: float, root: Path) -> tuple[list[str], float]:
    """One top-level layer's box: its name, its docstring's first sentence, its containers' columns."""
    inner_w = WIDTH - 2 * MARGIN - 24
    caption = textwrap.wrap(first_sentence(layer, root), int(inner_w / CHAR))
    parts = [_text(MARGIN + 12, y + 20, layer, size=14, weight="bold")]
    parts += [_text(MARGIN + 12, y + 20 + LINE * (i + 1), line) for i, line in enumerate(caption)]
    height = 28 + LINE * len(caption)
    columns = stack.inner.get(layer, [])
    if columns:
        gap = 40
        col_w = (inner_w - gap * (len(columns) - 1)) / len(columns)
        used = 0.0
        for n, (container, layers) in enumerate(columns):
            x = MARGIN + 12 + n * (col_w + gap)
            shapes, used = _column(x, y + height, col_w, container, layers)
            parts += shapes
            if n and container in stack.apart.get(layer, []):
                parts.append(_text(x - gap / 2, y + height + used / 2 + 4, "≠", size=18, weight="bold",
                                   anchor="middle"))
        height += used + 12
        if stack.apart.get(layer):
            names = ", ".join(m.rsplit(".", 1)[-1] for m in stack.apart[layer])
            parts.append(_text(MARGIN + 12, y + height + 4, f"≠ independent: {names} import nothing of each other"))
            height += LINE
    return [_box(MARGIN, y, WIDTH - 2 * MARGIN, height, FILL[0]), *parts], height


def layers_svg(pyproject: Path, root: Path) -> str:
    """The diagram of ``pyproject``'s contracts; ``root``: the directory holding the top package (captions)."""
    stack = read_contracts(pyproject)
    parts: list[str] = []
    y = float(MARGIN)
    for i, layer in enumerate(stack.layers):
        if i:
            parts.append(_arrow(WIDTH / 2, y - ARROW, y))
        shapes, height = _layer(stack, layer, y, root)
        parts += shapes
        y += height + ARROW
    y -= ARROW - 8
    for name in stack.also:
        parts.append(_text(MARGIN, y + 12, f"Also checked: {name}."))
        y += LINE
    height = y + MARGIN
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH} {height:.0f}" width="{WIDTH}" '
            f'height="{height:.0f}" font-family="system-ui, -apple-system, Segoe UI, Roboto, sans-serif">'
            f'<title>hil\'s layers: an arrow means "may import"</title>'
            f'<rect width="100%" height="100%" fill="#ffffff"/>\n' + "\n".join(parts) + "\n</svg>\n")
