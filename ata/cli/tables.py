"""Text tables that fit a terminal: every value whole, at any width from 80 columns.

A table too wide for the terminal is split into several that each repeat its first column (the
method), its other columns in order, as many in each as fit. A column is never narrower than
its longest value, nor than its header's longest word: values are never cut or broken, headers
wrap between words. `layout` plans it; the CLI draws each part with rich.
"""

from __future__ import annotations

from dataclasses import dataclass

PADDING = 2
"""Cell padding per column (one space each side)."""


@dataclass
class Part:
    """One of the tables a wide table is split into: its columns and their widths."""

    columns: list[int]
    widths: list[int]


def _frame(n: int) -> int:
    """The width of a boxed table's frame around n columns: padding and n + 1 rules."""
    return n * PADDING + n + 1


def layout(header: list[str], rows: list[list[str]], width: int, keep: int = 1) -> list[Part]:
    """The parts that show `rows` under `header` within `width` characters: the first `keep`
    columns in every part, the others in order, as many in each part as fit; each column as wide
    as its header where there is room, else as its longest value or header word."""
    least, ideal = [], []
    for i, name in enumerate(header):
        values = [len(r[i]) for r in rows if i < len(r)]
        widest = max(values, default=0)
        word = max((len(w) for w in name.split()), default=0)
        least.append(max(widest, word, 1))
        ideal.append(max(widest, len(name), 1))
    kept = list(range(min(keep, len(header))))
    parts: list[list[int]] = []
    current = list(kept)
    for i in range(len(kept), len(header)):
        wanted = current + [i]
        if len(current) > len(kept) and \
                sum(least[j] for j in wanted) + _frame(len(wanted)) > width:
            parts.append(current)
            current = list(kept) + [i]
        else:
            current = wanted
    parts.append(current)
    out = []
    for columns in parts:
        widths = [least[j] for j in columns]
        room = width - sum(widths) - _frame(len(columns))
        # the room left goes to the headers that would wrap, left to right
        for k, j in enumerate(columns):
            grow = min(max(room, 0), ideal[j] - widths[k])
            widths[k] += grow
            room -= grow
        out.append(Part(columns=columns, widths=widths))
    return out
