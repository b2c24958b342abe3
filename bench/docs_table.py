"""Write a benchmark's table into docs/benchmarks.md between its markers."""

from __future__ import annotations

import re
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"


def write_section(
    name: str,
    header: list[str],
    row: list[object] | None = None,
    intro: str = "",
    rows: list[list[object]] | None = None,
    docs: Path = DOCS,
) -> None:
    """Replace the ``<!-- NAME:begin -->`` ... ``<!-- NAME:end -->`` block (added
    at the end, after ``intro``, when missing) with a table of ``row`` (one row)
    or ``rows``, in ``docs`` (docs/benchmarks.md by default)."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    body = ([row] if row is not None else []) + list(rows or [])
    table = "\n".join(
        [
            begin,
            "| " + " | ".join(header) + " |",
            "|" + "---|" * len(header),
            *("| " + " | ".join(str(v) for v in r) + " |" for r in body),
            end,
        ]
    )
    text = docs.read_text() if docs.exists() else "# Benchmarks\n"
    if begin not in text:
        text = (
            text.rstrip("\n")
            + "\n\n"
            + (intro.strip() + "\n\n" if intro else "")
            + f"{begin}\n{end}\n"
        )
    docs.write_text(
        re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _: table, text, flags=re.S)
    )
