"""What the commands share: logging, ``NAME=VALUE`` pairs, and the converter's options
as click options, made from their one declaration (:data:`urdf2mjcf.options.OPTIONS`),
so that every command shows the same help and defaults.

Below ``cli.py``, ``batch.py`` and ``certify/command.py``: ``cli.py`` dispatches to the
other two, so none of them imports it.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import click
from click.core import ParameterSource

from .cli_types import BoundedInt, FiniteFloat, Keyed, KeyedChoice, KeyedFloat
from .options import BY_KEYWORD, OPTIONS, Choice, Number, Option

F = TypeVar("F", bound=Callable[..., Any])

def configure_logging(verbose: int, quiet: bool) -> None:
    level = (
        logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    )
    logging.basicConfig(
        level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr
    )


def pairs(values: tuple[str, ...], sep: str, what: str) -> dict[str, str]:
    """``NAME<sep>VALUE`` items -> {NAME: VALUE}; an item without ``sep`` or a name is a
    bad parameter (``what`` says what it should be)."""
    out = {}
    for item in values:
        name, found, value = item.partition(sep)
        if not found or not name:
            raise click.BadParameter(f"'{item}' is not {what}")
        out[name] = value
    return out


def _click_type(option: Option) -> Any:
    value = option.value
    if isinstance(value, Number):
        number: Any = (
            BoundedInt(int(value.low), int(value.high))
            if value.integer
            else FiniteFloat(value.low, value.high, low_open=value.low_open)
        )
        return KeyedFloat(number, option.key) if option.key else number
    if isinstance(value, Choice):
        return KeyedChoice(value.choices, option.key) if option.key else click.Choice(value.choices)
    if option.key:
        return Keyed(option.key, (option.metavar or "").partition("=")[2] or "VALUE")
    if value in ("file", "folder"):
        return click.Path(path_type=Path, dir_okay=value == "folder", file_okay=value == "file")
    return None  # text


def _click_option(option: Option) -> tuple[list[str], dict[str, Any]]:
    """The declarations and attributes of one converter option's click option, named by
    its keyword."""
    if not option.flags:
        raise ValueError(f"{option.keyword} is an option of the API only")
    decls = [*option.flags, option.keyword]
    if option.value == "switch":
        # A switch that is on by default is the flag that turns it off (--no-scene); one
        # with no default (trust_xacro: None) leaves the choice to the environment.
        on = option.default is not True
        return decls, {
            "is_flag": True,
            "flag_value": on,
            "default": option.default,
            "help": option.help,
        }
    keyed = option.key is not None
    return decls, {
        "type": _click_type(option),
        "multiple": option.repeatable or keyed,
        "default": None if keyed or option.repeatable else option.default,
        "show_default": option.show_default and option.default is not None and not keyed,
        "metavar": option.metavar,
        "help": option.help,
    }


QUIET: tuple[tuple[str, ...], dict[str, Any]] = (
    ("-q", "--quiet"),
    {
        "is_flag": True,
        "help": "Only errors and failures (a failed robot, a failing figure): no progress, "
        "notes or summary.",
    },
)
"""``-q`` of every command that has it: one meaning everywhere."""


def quiet_option() -> Callable[[F], F]:
    return click.option(*QUIET[0], **QUIET[1])


EVERY_ROBOT = tuple(o.keyword for o in OPTIONS if o.every_robot)
"""The converter's options that apply to every robot of a batch (``batch`` and ``view``
take them), in the order of the help."""


def converter_option(keyword: str) -> Callable[[F], F]:
    """The converter's option ``keyword`` (of :data:`~urdf2mjcf.options.OPTIONS`) as a
    decorator of its command."""
    decls, attrs = _click_option(BY_KEYWORD[keyword])
    return click.option(*decls, **attrs)


def converter_options(keywords: Iterable[str] | None = None) -> Callable[[F], F]:
    """The converter's options ``keywords`` (default: every one with a flag, as
    ``urdf2mjcf convert`` takes them) as one decorator of a command, in their order."""
    chosen = [o.keyword for o in OPTIONS if o.flags] if keywords is None else list(keywords)

    def decorate(f: F) -> F:
        for keyword in reversed(chosen):  # click lists the last decorator applied first
            f = converter_option(keyword)(f)
        return f

    return decorate


def converter_params(keywords: Iterable[str] = EVERY_ROBOT) -> list[click.Parameter]:
    """A fresh :class:`click.Option` for each of ``keywords``."""
    made = [_click_option(BY_KEYWORD[k]) for k in keywords]
    return [click.Option(decls, **attrs) for decls, attrs in made]


def converter_keywords(values: Mapping[str, Any]) -> dict[str, Any]:
    """The converter's options the user gave on the command line, of the command's
    ``values``, as keywords of :func:`~urdf2mjcf.options.make_options` (an option left
    out takes its declared default there)."""
    ctx = click.get_current_context()
    return {
        k: v
        for k, v in values.items()
        if k in BY_KEYWORD and ctx.get_parameter_source(k) is not ParameterSource.DEFAULT
    }
