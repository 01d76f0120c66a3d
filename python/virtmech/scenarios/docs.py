"""The tables of docs/scenarios.md, made from the core's tables: the controller's and the
mechanism set's settings (virtmech.CONTROLLER_SETTINGS, SET_SETTINGS) and the kinds of
device, mechanism and shape with their parameters (virtmech.kinds). Each table sits in the
document between the lines ``<!-- table: NAME -->`` and ``<!-- end of table -->``.

    python -m virtmech.scenarios.docs docs/scenarios.md          # rewrites the tables
    python -m virtmech.scenarios.docs docs/scenarios.md --check  # exit 1 where they differ
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

from .. import _core

_BLOCK = re.compile(r"(<!-- table: (\w+) -->\n)(.*?)(<!-- end of table -->)", re.S)


def _number(x) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return _number(v)


def _range(lo: float, hi: float, above: bool, unit: str = "") -> str:
    parts = []
    if math.isfinite(lo):
        parts.append(f"{'>' if above else '≥'} {_number(lo)}")
    if math.isfinite(hi):
        parts.append(f"≤ {_number(hi)}")
    text = ", ".join(parts)
    return f"{text} [{unit}]" if unit and text else text


def settings_table(rows: list[dict], skip: tuple[str, ...] = ()) -> str:
    """A settings table: key, kind, default, range, meaning."""
    out = ["| key | type | default | range | meaning |", "| --- | --- | --- | --- | --- |"]
    for r in rows:
        if r["name"] in skip:
            continue
        if r["kind"] == "vector6":
            kind, default, rng = "6 numbers", "derived", "each ≥ 0"
        elif r["kind"] == "choice":
            kind = " \\| ".join(f'"{c}"' for c in r["choices"])
            default, rng = _value(r["default"]), ""
        else:
            kind = r["kind"]
            default = _value(r["default"])
            rng = _range(r["min"], r["max"], r["min_exclusive"])
            rng += " or inf" if r["inf_allowed"] else ""
        unit = f" [{r['unit']}]" if r["unit"] else ""
        out.append(f"| `{r['name']}` | {kind} | {default} | {rng} | {r['doc']}{unit} |")
    return "\n".join(out)


def _param(p: dict) -> str:
    """A parameter as a kind table lists it: its name, then required / its default, and
    its range or shape."""
    if p["required"]:
        state = "required"
    elif "default" in p:
        state = _value(p["default"])
    else:
        state = "optional"
    extra = ""
    if p["kind"] in ("number", "integer"):
        extra = _range(p["min"], p["max"], p["min_exclusive"], p["unit"])
    elif p["kind"] == "array":
        shape = ", ".join("n" if s < 0 else str(s) for s in p["shape"])
        extra = f"({shape}{',' if len(p['shape']) == 1 else ''})" + (
            f" [{p['unit']}]" if p["unit"] else "")
    elif p["kind"] in ("curve", "surface"):
        extra = f"a {p['kind']} table"
    elif p["kind"] == "tables":
        extra = "[[tables]] of " + ", ".join(f"`{f['name']}`" for f in p["fields"])
    return f"`{p['name']}` ({state}{'; ' + extra if extra else ''})"


def kinds_table(what: str) -> str:
    """A table of the registered kinds of `what`: type, meaning, keys."""
    out = ["| type | meaning | keys |", "| --- | --- | --- |"]
    for k in _core.kinds(what):
        keys = ", ".join(_param(p) for p in k["params"])
        out.append(f"| `{k['name']}` | {k['doc']} | {keys} |")
    return "\n".join(out)


def tables() -> dict[str, str]:
    """Every generated table by its name in the document."""
    return {
        "controller": settings_table(_core.CONTROLLER_SETTINGS),
        "set": settings_table(_core.SET_SETTINGS, skip=("period_s",)),
        "device": kinds_table("device"),
        "mechanism": kinds_table("mechanism"),
        "shape": kinds_table("surface") + "\n" + "\n".join(kinds_table("curve").split("\n")[2:]),
    }


def render(text: str) -> str:
    """The document with every generated table made anew (KeyError for an unknown name)."""
    made = tables()
    return _BLOCK.sub(lambda m: m.group(1) + made[m.group(2)] + "\n" + m.group(4), text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m virtmech.scenarios.docs", description=__doc__)
    ap.add_argument("path", type=Path, help="docs/scenarios.md")
    ap.add_argument("--check", action="store_true", help="exit 1 where the tables differ")
    a = ap.parse_args(argv)
    text = a.path.read_text(encoding="utf-8")
    new = render(text)
    if a.check:
        if new != text:
            sys.stderr.write(f"{a.path}: its tables differ from the core's; run "
                             f"python -m virtmech.scenarios.docs {a.path}\n")
            return 1
        return 0
    a.path.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
