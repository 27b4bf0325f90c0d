"""Regenerate the parts of the docs derived from the parameter tables.

* ``docs/api.md``: the parameter tables between the ``FAN_PARAMS`` and the
  ``MESH_PARAMS`` marker comments, from
  :func:`fancloud_vtk.params.markdown_table`;
* ``fancloud_vtk/accessor.pyi``: the signatures of the accessor verbs
  (``fans``: ``FAN_PARAMS + INPUT_PARAMS``, ``mesh``: ``FAN_PARAMS +
  INPUT_PARAMS + MESH_PARAMS``, ... as in ``VERBS``) between their
  markers, from the same tables.

It also checks that ``docs/api.md`` names every entry of
``fancloud_vtk.__all__``, ``fancloud_vtk.algorithms.__all__`` and
``fancloud_vtk.core.mesh_stats.__all__`` (as ```name``), every public
verb of the accessor (as ``fancloud.verb``), every subcommand of the
``fancloud`` command (as ``fancloud command``) and every benchmark (as
``fancloud bench mode``).

Usage: ``python scripts/gen_docs.py`` rewrites the files; ``--check`` only
reports (exit status 1) when they are out of date.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import fancloud_vtk  # noqa: E402
import fancloud_vtk.algorithms  # noqa: E402
import fancloud_vtk.core.mesh_stats  # noqa: E402
from fancloud_vtk.params import (  # noqa: E402
    ENTROPY_PARAMS,
    FAN_PARAMS,
    INPUT_PARAMS,
    MESH_PARAMS,
    REDUCE_PARAMS,
    REFINE_PARAMS,
    SELECTIVE_PARAMS,
    VDFC_PARAMS,
    Param,
    markdown_table,
)

API_MD = ROOT / "docs" / "api.md"
STUB = ROOT / "fancloud_vtk" / "accessor.pyi"

#: Accessor verbs whose stub signature is generated: name -> (table, one-line docstring).
VERBS = {
    "fans": (
        FAN_PARAMS + INPUT_PARAMS,
        "Build the fan cloud of the dataset's points (paper section 3); a new PolyData.",
    ),
    "mesh": (
        FAN_PARAMS + INPUT_PARAMS + MESH_PARAMS,
        "Triangle mesh of the dataset's fan cloud or points (paper section 4); a new PolyData.",
    ),
    "entropy": (
        FAN_PARAMS + INPUT_PARAMS + ENTROPY_PARAMS,
        "The entropy of every point as point arrays (paper section 5); a new PolyData.",
    ),
    "reduce": (
        FAN_PARAMS + INPUT_PARAMS + REDUCE_PARAMS,
        "Reduce to an exact number of points by entropy (paper section 5); a new PolyData.",
    ),
    "selective": (
        FAN_PARAMS + INPUT_PARAMS + REDUCE_PARAMS[:-1] + SELECTIVE_PARAMS,
        "Reduce, smooth, refine only a region of interest (Figure 11); a new PolyData.",
    ),
    "refine": (
        FAN_PARAMS + INPUT_PARAMS + REFINE_PARAMS,
        "Refine beyond the input resolution by entropy (paper section 7); a new PolyData.",
    ),
    "vdfc": (
        FAN_PARAMS + INPUT_PARAMS + VDFC_PARAMS,
        "The merge forest of the view-dependent fan cloud (paper section 8).",
        "PyVistaViewDependentFanCloud",
    ),
}

#: Tables rendered into docs/api.md between ``BEGIN <NAME>`` / ``END <NAME>`` markers.
TABLES = {
    "FAN_PARAMS": FAN_PARAMS,
    "INPUT_PARAMS": INPUT_PARAMS,
    "MESH_PARAMS": MESH_PARAMS,
    "ENTROPY_PARAMS": ENTROPY_PARAMS,
    "REDUCE_PARAMS": REDUCE_PARAMS,
    "SELECTIVE_PARAMS": SELECTIVE_PARAMS,
    "REFINE_PARAMS": REFINE_PARAMS,
    "VDFC_PARAMS": VDFC_PARAMS,
}


def stub_signature(table: tuple[Param, ...], name: str = "fans", doc: str | None = None,
                   returns: str = "pv.PolyData") -> str:
    """The accessor method's signature (keyword-only, from the table) as stub lines."""
    types = {"int": "int", "float": "float", "bool": "bool", "str": "str"}
    doc = VERBS[name][1] if doc is None else doc
    lines = [f"    def {name}(", "        self,", "        *,"]
    for p in table:
        if p.kind == "choice":
            kind = "Literal[" + ", ".join(f'"{c}"' for c in p.choices) + "]"
            default = f'"{p.default}"'
        elif p.kind == "vector":
            kind = "tuple[float, ...]" if p.size > 4 else \
                "tuple[" + ", ".join(["float"] * p.size) + "]"
            default = repr(p.default)
        elif p.kind == "str":
            kind = "str"
            default = f'"{p.default}"'
        else:
            kind = types[p.kind]
            default = repr(p.default)
        lines.append(f"        {p.name}: {kind} = {default},")
    lines += [
        "        progress_bar: bool = False,",
        f"    ) -> {returns}:",
        f'        """{doc}"""',
    ]
    return "\n".join(lines)


def replace_between(text: str, begin: str, end: str, body: str, path: Path) -> str:
    """``text`` with the lines strictly between the ``begin`` and ``end`` lines replaced."""
    pattern = re.compile(rf"(^[^\n]*{re.escape(begin)}[^\n]*\n)(.*?)(^[^\n]*{re.escape(end)})",
                         re.S | re.M)
    if not pattern.search(text):
        raise SystemExit(f"gen_docs: markers {begin!r} / {end!r} not found in {path}")
    return pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(3), text, count=1)


def targets() -> list[tuple[Path, str, str, str]]:
    """Every generated block: (file, begin marker, end marker, content)."""
    out = [(API_MD, f"BEGIN {name}", f"END {name}", markdown_table(table))
           for name, table in TABLES.items()]
    for verb, (table, doc, *returns) in VERBS.items():
        out.append((STUB, f"BEGIN GENERATED {verb}", f"END GENERATED {verb}",
                    stub_signature(table, verb, doc, *returns)))
    return out


def _subcommands(parser: argparse.ArgumentParser) -> list[str]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return list(action.choices)


def missing_names(api_text: str) -> list[str]:
    """Public names, verbs and commands that docs/api.md does not mention."""
    from fancloud_vtk.accessor import FanCloudAccessor
    from fancloud_vtk.bench import make_parser as bench_parser
    from fancloud_vtk.cli import make_parser

    names = (list(fancloud_vtk.__all__) + list(fancloud_vtk.algorithms.__all__)
             + list(fancloud_vtk.core.mesh_stats.__all__))
    missing = [n for n in names if f"`{n}" not in api_text]
    verbs = [v for v in vars(FanCloudAccessor) if not v.startswith("_")]
    missing += [f"fancloud.{v}" for v in verbs if f"fancloud.{v}" not in api_text]
    commands = [f"fancloud {c}" for c in _subcommands(make_parser())]
    commands += [f"fancloud bench {m}" for m in _subcommands(bench_parser())]
    missing += [c for c in commands if f"`{c}" not in api_text]
    return missing


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="report stale files, write nothing")
    args = parser.parse_args(argv)

    new_text: dict[Path, str] = {}
    for path, begin, end, body in targets():
        old = new_text.get(path) or path.read_text(encoding="utf-8")
        new_text[path] = replace_between(old, begin, end, body, path)
    stale = []
    for path, new in new_text.items():
        if new != path.read_text(encoding="utf-8"):
            stale.append(path)
            if not args.check:
                path.write_text(new, encoding="utf-8")
    missing = missing_names(API_MD.read_text(encoding="utf-8"))

    for path in stale:
        verb = "out of date" if args.check else "updated"
        print(f"gen_docs: {path.relative_to(ROOT)} {verb}")
    if missing:
        print(f"gen_docs: docs/api.md does not document {missing}")
    if not stale and not missing:
        print("gen_docs: docs/api.md and fancloud_vtk/accessor.pyi are up to date")
    return 1 if missing or (args.check and stale) else 0


if __name__ == "__main__":
    sys.exit(main())
