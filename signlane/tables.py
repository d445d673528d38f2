"""One table style for everything the project prints: commands, evaluations and benchmarks.

`table(headers, rows)` lays out columns (text left, numbers right, a rule under the header);
`markdown=True` gives the same table as GitHub markdown, for pasting into the README; `pairs(rows)`
is the two-column "measure  value" form of a report. Cells are formatted by the caller (the
number of decimals is part of what a column means), so everything here is a string by then.
"""
from __future__ import annotations

import re
from typing import Iterable, Sequence

_NUMERIC = re.compile(r"^[-+]?[\d.,]+\s*(%|ms|s|x|/.*)?$")


def _is_number(cell: str) -> bool:
    return bool(_NUMERIC.match(cell.strip())) if cell.strip() else True


def table(headers: Sequence[str], rows: Iterable[Sequence[object]], markdown: bool = False) -> str:
    """A table of str()-ed cells: a column whose cells all read as numbers is right-aligned."""
    head = [str(h) for h in headers]
    body = [[str(c) for c in r] for r in rows]
    for r in body:
        if len(r) != len(head):
            raise ValueError(f"table row has {len(r)} cells for {len(head)} columns: {r}")
    if markdown:
        return "\n".join([markdown_row(head), "|" + "---|" * len(head)] + [markdown_row(r) for r in body])
    widths = [max([len(h)] + [len(r[i]) for r in body]) for i, h in enumerate(head)]
    right = [bool(body) and all(_is_number(r[i]) for r in body) for i in range(len(head))]

    def line(cells):
        return "  ".join(c.rjust(w) if rj else c.ljust(w) for c, w, rj in zip(cells, widths, right)).rstrip()
    return "\n".join([line(head), "  ".join("-" * w for w in widths)] + [line(r) for r in body])


def markdown_row(cells: Sequence[object]) -> str:
    """One row of a markdown table (for tables printed row by row as results come in)."""
    return "| " + " | ".join(str(c) for c in cells) + " |"


def pairs(rows: Iterable[tuple[str, object]]) -> str:
    """'measure  value' lines, the measures padded to one width."""
    rows = [(str(k), str(v)) for k, v in rows]
    w = max((len(k) for k, _ in rows), default=0)
    return "\n".join(f"{k.ljust(w)}  {v}" for k, v in rows)
