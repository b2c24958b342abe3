"""Write a benchmark's table into docs/benchmarks.md between its markers."""

from __future__ import annotations

import re
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"


def write_section(name: str, header: list[str], row: list[object], intro: str = "") -> None:
    """Replace the ``<!-- NAME:begin -->`` ... ``<!-- NAME:end -->`` block (added
    at the end, after ``intro``, when missing) with a one-row table."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    table = "\n".join(
        [
            begin,
            "| " + " | ".join(header) + " |",
            "|" + "---|" * len(header),
            "| " + " | ".join(str(v) for v in row) + " |",
            end,
        ]
    )
    text = DOCS.read_text() if DOCS.exists() else "# Benchmarks\n"
    if begin not in text:
        text = (
            text.rstrip("\n")
            + "\n\n"
            + (intro.strip() + "\n\n" if intro else "")
            + f"{begin}\n{end}\n"
        )
    DOCS.write_text(
        re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _: table, text, flags=re.S)
    )
