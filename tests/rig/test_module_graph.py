"""The module graph of every package: no import cycles between modules, and no module outside
a ``kinds`` folder asks a config which kind it is by name."""

from __future__ import annotations

import ast
from pathlib import Path

import grimp

from rig.kinds import kind_names

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = (
    "rig", "sim", "orchestrator", "studies", "processing", "calibration", "render", "drivers"
)  # fmt: skip


def test_no_import_cycles_between_modules():
    """An import ``a → b`` closes a cycle when ``b`` leads back to ``a``. Imports under
    ``TYPE_CHECKING`` never run and are left out; imports inside functions count."""
    graph = grimp.build_graph(*PACKAGES, exclude_type_checking_imports=True, cache_dir=None)
    cycles = set()
    for module in sorted(graph.modules):
        for imported in graph.find_modules_directly_imported_by(module):
            back = graph.find_shortest_chain(importer=imported, imported=module)
            if back is not None:
                cycles.add((module, *back))
    assert sorted(cycles) == []


def _literals(node: ast.expr) -> set[str]:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return {node.value}
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return set().union(*(_literals(e) for e in node.elts))
    return set()


def _kind_tests(path: Path, root: Path = ROOT) -> list[str]:
    """Comparisons of a ``kind`` with a rig kind's name (``config.kind == "bonn"``,
    ``kind in ("virtex", "bonn")``), as ``path:line``; a capture's or a lamp's kind
    (``step.kind == "mdf"``) names no rig kind and is another thing."""
    rig_kinds = set(kind_names())
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        a_kind = any(
            (isinstance(side, ast.Attribute) and side.attr == "kind")
            or (isinstance(side, ast.Name) and side.id == "kind")
            for side in sides
        )
        if a_kind and set().union(*(_literals(side) for side in sides)) & rig_kinds:
            found.append(f"{path.relative_to(root)}:{node.lineno}")
    return found


def test_no_module_outside_the_kinds_tests_a_config_kind_by_name():
    found = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            if "kinds" not in path.relative_to(ROOT).parts:
                found += _kind_tests(path)
    assert found == []


def test_the_check_finds_a_kind_test(tmp_path):
    (tmp_path / "m.py").write_text(
        'def f(config, kind):\n    return config.kind == "bonn" or kind in ("virtex",)\n'
    )
    assert _kind_tests(tmp_path / "m.py", tmp_path) == ["m.py:2", "m.py:2"]
    (tmp_path / "m.py").write_text('def f(step):\n    return step.kind == "mdf"\n')
    assert _kind_tests(tmp_path / "m.py", tmp_path) == []
