"""Option values that start with ``-``, for the ``fancloud`` command and ``fancloud bench``.

argparse reads ``--region-center -0.1,0.3,0.7`` as two options (and fails with
"expected one argument"); :func:`join_negative_values` passes such a value as
``--region-center=-0.1,0.3,0.7`` before parsing. Both parsers (:mod:`fancloud_vtk.cli`,
:mod:`fancloud_vtk.bench`) have subcommands; only the options of the one given are
joined.
"""

from __future__ import annotations

import argparse
import re

#: a value argparse would take for an option: a negative number or a list of them
#: ("-0.1,0.3,0.7", "-3,0,0;0,0,0;0,0,1;40", "-.5")
NEGATIVE_VALUE = re.compile(r"-[0-9.]")


def value_options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """The option strings of ``parser`` that take exactly one value."""
    return {flag: action for action in parser._actions if action.option_strings
            and action.nargs is None for flag in action.option_strings}


def join_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with every value that starts like a negative number joined to its option.

    argparse reads ``--region-center -0.1,0.3,0.7`` as two options (and fails with
    "expected one argument"): such a value is passed as ``--region-center=-0.1,0.3,0.7``
    (``-o-1.png`` for a short option). Only options of the subcommand that take a value
    are joined (abbreviations too, when they name one option); nothing after ``--``.
    """
    sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
    command = next((i for i, arg in enumerate(argv) if not arg.startswith("-")), None)
    if sub is None or command is None or argv[command] not in sub.choices:
        return argv
    subparser = sub.choices[argv[command]]
    takes_value = value_options(subparser)
    every_flag = [f for a in subparser._actions for f in a.option_strings]
    out, i = argv[:command + 1], command + 1
    while i < len(argv):
        arg = argv[i]
        if arg == "--":
            out.extend(argv[i:])
            break
        action = takes_value.get(arg)
        if action is None and arg.startswith("--") and "=" not in arg:
            named = {takes_value.get(f) for f in every_flag if f.startswith(arg)}
            action = named.pop() if len(named) == 1 else None
        if action is not None and i + 1 < len(argv):
            value = argv[i + 1]
            if NEGATIVE_VALUE.match(value):
                out.append(f"{arg}={value}" if arg.startswith("--") else arg + value)
            else:
                out += [arg, value]  # the value is the option's, whatever it looks like
            i += 2
            continue
        out.append(arg)
        i += 1
    return out
