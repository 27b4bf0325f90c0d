"""Regenerate the parts of the docs derived from the parameter tables.

* ``docs/api.md``: the parameter table between the ``FAN_PARAMS`` marker
  comments, from :func:`fancloud_vtk.params.markdown_table`;
* ``fancloud_vtk/accessor.pyi``: the ``fans`` signature between its markers,
  from the same table.

It also checks that ``docs/api.md`` names every entry of
``fancloud_vtk.__all__`` and ``fancloud_vtk.algorithms.__all__``.

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
from fancloud_vtk.params import FAN_PARAMS, Param, markdown_table  # noqa: E402

API_MD = ROOT / "docs" / "api.md"
STUB = ROOT / "fancloud_vtk" / "accessor.pyi"


def stub_signature(table: tuple[Param, ...], name: str = "fans") -> str:
    """The accessor method's signature (keyword-only, from the table) as stub lines."""
    types = {"int": "int", "float": "float", "bool": "bool"}
    lines = [f"    def {name}(", "        self,", "        *,"]
    for p in table:
        if p.kind == "choice":
            kind = "Literal[" + ", ".join(f'"{c}"' for c in p.choices) + "]"
            default = f'"{p.default}"'
        else:
            kind = types[p.kind]
            default = repr(p.default)
        lines.append(f"        {p.name}: {kind} = {default},")
    lines += [
        "        progress_bar: bool = False,",
        "    ) -> pv.PolyData:",
        '        """Build the fan cloud of the dataset\'s points (paper section 3); '
        'a new PolyData."""',
    ]
    return "\n".join(lines)


def replace_between(text: str, begin: str, end: str, body: str, path: Path) -> str:
    """``text`` with the lines strictly between the ``begin`` and ``end`` lines replaced."""
    pattern = re.compile(rf"(^[^\n]*{re.escape(begin)}[^\n]*\n)(.*?)(^[^\n]*{re.escape(end)})",
                         re.S | re.M)
    if not pattern.search(text):
        raise SystemExit(f"gen_docs: markers {begin!r} / {end!r} not found in {path}")
    return pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(3), text, count=1)


def missing_names(api_text: str) -> list[str]:
    """Public names of the package that docs/api.md does not mention (as ``name``)."""
    names = list(fancloud_vtk.__all__) + list(fancloud_vtk.algorithms.__all__)
    return [n for n in names if f"`{n}" not in api_text]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="report stale files, write nothing")
    args = parser.parse_args(argv)

    targets = {
        API_MD: ("BEGIN FAN_PARAMS", "END FAN_PARAMS", markdown_table(FAN_PARAMS)),
        STUB: ("BEGIN GENERATED fans", "END GENERATED fans", stub_signature(FAN_PARAMS)),
    }
    stale = []
    for path, (begin, end, body) in targets.items():
        old = path.read_text(encoding="utf-8")
        new = replace_between(old, begin, end, body, path)
        if new != old:
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
