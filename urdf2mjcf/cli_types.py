"""Checked number and ``KEY=VALUE`` types for command-line options.

A number a user types is untrusted input like any file: ``nan``, ``inf`` and
``1e300`` parse as floats, and a negative count parses as an int. These click
parameter types refuse anything outside a documented range, so a bad value is
one ``error:`` line naming the option (click's usage error, exit 2), never a
crash deeper in. Every message states the valid range.

API:

- ``FiniteFloat(low, high, low_open=False)``: a finite float in ``[low, high]``
  (``(low, high]`` with ``low_open``).
- ``BoundedInt(low, high)``: an integer in ``[low, high]``.
- ``Keyed(key_name, value_name)``: ``KEY=VALUE``, the value as given; converts to
  ``(key, value)``. ``KeyedFloat(type, key_name)``: the value a number checked by a
  ``FiniteFloat``; ``KeyedChoice(choices, key_name)``: one of ``choices``.
"""

from __future__ import annotations

from typing import Any

import click

from .untrusted import BadNumber, excerpt, parse_number, read_whole


def _fmt(x: float) -> str:
    return f"{x:g}"


class FiniteFloat(click.ParamType):
    """A finite float within ``[low, high]`` (``(low, high]`` with ``low_open``)."""

    name = "number"

    def __init__(self, low: float, high: float, low_open: bool = False) -> None:
        if not low < high:
            raise ValueError("low must be below high")
        self.low = low
        self.high = high
        self.low_open = low_open

    @property
    def range_text(self) -> str:
        """The valid range in words, e.g. 'above 0 and at most 1e+06'."""
        lo = f"above {_fmt(self.low)}" if self.low_open else f"at least {_fmt(self.low)}"
        return f"a finite number {lo} and at most {_fmt(self.high)}"

    def check(self, value: Any) -> float | str:
        """``value`` as a float, or the reason it is refused."""
        try:
            x = parse_number(value)  # the one number reader (decimal text, not too long)
        except BadNumber as exc:
            return f"{exc}; expected {self.range_text}"
        too_low = x <= self.low if self.low_open else x < self.low
        if too_low or x > self.high:
            return f"{excerpt(str(value), 40)} is out of range; expected {self.range_text}"
        return x

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        result = self.check(value)
        if isinstance(result, str):
            self.fail(result, param, ctx)
        return result

    def __repr__(self) -> str:
        return f"FiniteFloat({self.low!r}, {self.high!r}, low_open={self.low_open!r})"


class BoundedInt(click.ParamType):
    """An integer within ``[low, high]`` (a float or ``nan`` is refused)."""

    name = "integer"

    def __init__(self, low: int, high: int) -> None:
        if not low <= high:
            raise ValueError("low must not be above high")
        self.low = low
        self.high = high

    @property
    def range_text(self) -> str:
        return f"an integer from {self.low} to {self.high}"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        try:
            # int() alone would accept '1_000' and spend time on a 100,000-digit string
            n = read_whole(value, low=-(10**30), high=10**30)
        except BadNumber:
            shown = excerpt(str(value).strip(), 40)
            self.fail(f"'{shown}' is not an integer; expected {self.range_text}", param, ctx)
        if not self.low <= n <= self.high:
            self.fail(f"{n} is out of range; expected {self.range_text}", param, ctx)
        return n

    def __repr__(self) -> str:
        return f"BoundedInt({self.low!r}, {self.high!r})"


class Keyed(click.ParamType):
    """``KEY=VALUE``; converts to ``(key, value)``, the value as :meth:`checked` reads it
    (here: the text as given)."""

    name = "key=value"

    def __init__(self, key_name: str = "KEY", value_name: str = "VALUE") -> None:
        self.key_name = key_name
        self.value_name = value_name

    def checked(
        self, key: str, raw: str, param: click.Parameter | None, ctx: click.Context | None
    ) -> Any:
        return raw

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        key, found, raw = str(value).partition("=")
        if not found or not key:
            shown = f"{self.key_name}={self.value_name}"
            self.fail(f"'{excerpt(str(value), 40)}' is not {shown}", param, ctx)
        return (key, self.checked(key, raw, param, ctx))


class KeyedFloat(Keyed):
    """``KEY=NUMBER``, the number checked by ``number``; converts to ``(key, value)``."""

    name = "key=number"

    def __init__(self, number: FiniteFloat, key_name: str = "KEY") -> None:
        super().__init__(key_name, "NUMBER")
        self.number = number

    def checked(
        self, key: str, raw: str, param: click.Parameter | None, ctx: click.Context | None
    ) -> Any:
        result = self.number.check(raw)
        if isinstance(result, str):
            self.fail(f"{excerpt(key, 40)}: {result}", param, ctx)
        return result


class KeyedChoice(Keyed):
    """``KEY=CHOICE``, the choice one of ``choices``; converts to ``(key, choice)``."""

    name = "key=choice"

    def __init__(self, choices: tuple[str, ...], key_name: str = "KEY") -> None:
        super().__init__(key_name)
        self.choices = choices

    def checked(
        self, key: str, raw: str, param: click.Parameter | None, ctx: click.Context | None
    ) -> Any:
        if raw not in self.choices:
            self.fail(
                f"{excerpt(key, 40)}: '{excerpt(raw, 20)}' is not one of "
                f"{', '.join(self.choices)}",
                param,
                ctx,
            )
        return raw
