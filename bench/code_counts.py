"""The counts of issue 27 ("a layout always exists"), so that before and after are one command.

    .venv/bin/python bench/code_counts.py [ROOT]       # ROOT: a checkout (default: this one)

* run-mode branches: lines matching ``(dist|grid|owned|layout|_T)\w* is (not )?None`` (the
  architecture review's definition) in kapsel/**/*.py outside the distributed implementation
  (kapsel/parallel/, and the pencil layout kapsel/mesh/pencil.py, which was in
  kapsel/parallel/ when the review counted) and the run level (kapsel/cli.py,
  kapsel/startup.py), per file;
* ``Distributed*`` classes (their definitions);
* mutually importing package pairs: kapsel's subpackages and top-level modules (kapsel.fluid,
  kapsel.mesh.grid, ...) of which each imports the other somewhere (imports inside functions too);
* the longest function or method (lines from its ``def`` to its last statement).
"""
from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

BRANCH = re.compile(r"(dist|grid|owned|layout|_T)\w* is (not )?None")


def _unit(rel: Path) -> str:
    """The package or top-level module of kapsel a file belongs to ('fluid', 'grid')."""
    parts = rel.parts
    return parts[0] if len(parts) > 1 else rel.stem


def _imported_units(tree, rel: Path) -> set:
    """Units of kapsel that a module imports (absolute kapsel.x or relative imports)."""
    pkg = list(rel.parent.parts)          # package path of the module inside kapsel
    out = set()
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name.split(".") for a in node.names if a.name.split(".")[0] == "kapsel"]
            names = [n[1:] for n in names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[:len(pkg) - (node.level - 1)] if node.level > 1 else list(pkg)
                if node.level - 1 > len(pkg):
                    continue
                mod = base + (node.module.split(".") if node.module else [])
                if node.module is None:                  # from . import a, b
                    names = [mod + [a.name] for a in node.names]
                else:
                    names = [mod]
            elif node.module and node.module.split(".")[0] == "kapsel":
                mod = node.module.split(".")[1:]
                names = [mod + [a.name] for a in node.names] if not mod else [mod]
        for n in names:
            if n:
                out.add(n[0])
    return out


def counts(root: Path) -> dict:
    src = root / "kapsel"
    branches, classes, imports, longest = {}, [], {}, (0, "")
    for path in sorted(src.rglob("*.py")):
        rel = path.relative_to(src)
        text = path.read_text()
        name = f"kapsel/{rel.as_posix()}"
        if not (rel.parts[0] == "parallel" or name in ("kapsel/cli.py", "kapsel/startup.py",
                                                         "kapsel/mesh/pencil.py")):
            n = sum(1 for line in text.splitlines() if BRANCH.search(line))
            if n:
                branches[name] = n
        tree = ast.parse(text)
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef) and node.name.startswith("Distributed"):
                classes.append(f"{name}:{node.lineno} {node.name}")
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                size = node.end_lineno - node.lineno + 1
                if size > longest[0]:
                    longest = (size, f"{name}:{node.lineno} {node.name}")
        unit = _unit(rel)
        imports.setdefault(unit, set()).update(_imported_units(tree, rel) - {unit})
    cycles = sorted({tuple(sorted((a, b))) for a, bs in imports.items() for b in bs
                     if a in imports.get(b, ())})
    return {"branches": branches, "classes": classes, "cycles": cycles, "longest": longest}


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    root = Path(argv[0]) if argv else Path(__file__).resolve().parents[1]
    c = counts(root)
    print(f"run-mode branches outside the run level: {sum(c['branches'].values())}")
    for f, n in sorted(c["branches"].items(), key=lambda kv: (-kv[1], kv[0])):
        print(f"  {n:3d}  {f}")
    print(f"Distributed* classes: {len(c['classes'])}")
    for k in c["classes"]:
        print(f"  {k}")
    print(f"mutually importing package pairs: {len(c['cycles'])}")
    for a, b in c["cycles"]:
        print(f"  {a} <-> {b}")
    print(f"longest function: {c['longest'][0]} lines, {c['longest'][1]}")


if __name__ == "__main__":
    main()
