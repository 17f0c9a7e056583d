"""What several `atr` commands and scripts share in their arguments: a parser that shows a script's
docstring as written, repeatable options, and options handed on by name.
"""

from __future__ import annotations

import argparse
from typing import Any


def script_parser(doc: str | None) -> argparse.ArgumentParser:
    """The parser of a script (a bench) whose help is its docstring as written, example commands kept."""
    return argparse.ArgumentParser(
        description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )


def add_repeatable(
    parser: argparse.ArgumentParser,
    flag: str,
    help_text: str,
    default_text: str | None = None,
    **kwargs: Any,
) -> None:
    """An option that may be given any number of times, collected into a list (empty when not given).

    Args:
        parser: the parser to add it to.
        flag: the option, e.g. "--scenario".
        help_text: what one occurrence means; the help adds that it repeats.
        default_text: what applies when it is not given, for the help (e.g. "all").
        kwargs: more of `add_argument`'s keywords (type, metavar, dest).

    """
    note = "repeatable" if default_text is None else f"repeatable; default {default_text}"
    parser.add_argument(flag, action="append", default=[], help=f"{help_text} ({note})", **kwargs)


def forwarded(args: argparse.Namespace, *names: str) -> dict[str, Any]:
    """The named arguments as keywords, for a function whose parameters are named as the options are."""
    return {name: getattr(args, name) for name in names}
