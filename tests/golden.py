"""Canonical form of MJCF for golden-file comparison.

Floats are rounded to 9 significant digits (so a last-bit change in a
library's arithmetic does not fail the test, while any real change does),
content-hash suffixes of asset names are masked (they follow from bytes that
the mesh tests check on their own), and the XML is written in C14N form.
"""

from __future__ import annotations

import re

from lxml import etree

_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")
_HASH = re.compile(r"_[0-9a-f]{10}(?=\.|$|\b)")


def _canon_value(value: str) -> str:
    parts = value.split()
    if parts and all(_NUMBER.match(p) for p in parts):
        out = []
        for p in parts:
            x = float(f"{float(p):.9g}")
            out.append("0" if x == 0 else f"{x:.9g}")
        return " ".join(out)
    return _HASH.sub("_#", value)


def canonical(xml: bytes) -> str:
    root = etree.fromstring(
        xml, parser=etree.XMLParser(remove_blank_text=True, remove_comments=True)
    )
    for el in root.iter():
        for key, value in el.attrib.items():
            el.set(key, _canon_value(value))
    etree.indent(root, space="  ")
    return etree.tostring(root, method="c14n").decode() + "\n"
