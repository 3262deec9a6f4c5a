"""The package is laid out as the pipeline: no module imports from a layer above its own,
and no import cycle exists (imports inside functions included)."""

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "jaxgait"

#: Layers from the bottom: a module may import from its own layer and the ones below.
LAYERS = {
    "core": 0,
    "body": 1,
    "muscles": 2,
    "world": 3,
    "control": 4,
    "sim": 5,
    "taga": 6,
    "analysis": 7,
    "optim": 8,
    "models": 9,
    "presets": 10,
    "train": 11,
    "evaluation": 12,
    "evaluate": 12,
    "robustness": 12,
    "render": 12,
    "spinal": 13,
    "cli": 14,
    "__main__": 14,
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PKG.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PKG.rglob("*.py") if "_resources" not in p.parts}


MODULES = _modules()


def _resolve(name: str) -> str:
    """The most specific jaxgait module a dotted name refers to."""
    while name not in MODULES and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


def _imports(mod: str, path: Path) -> set[str]:
    """jaxgait modules imported anywhere in ``path`` (module level and inside functions)."""
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {_resolve(a.name) for a in node.names if a.name.startswith("jaxgait")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = mod.split(".")
                base = base if is_pkg else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                src = ".".join(base + ([node.module] if node.module else []))
            else:
                src = node.module or ""
            if not src.startswith("jaxgait"):
                continue
            for a in node.names:
                full = f"{src}.{a.name}"
                out.add(_resolve(full) if full in MODULES else _resolve(src))
    out.discard(mod)
    return {m for m in out if m != "jaxgait"}


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def _layer(mod: str) -> int | None:
    parts = mod.split(".")
    if len(parts) < 2:
        return None
    return LAYERS.get(parts[1])


def test_every_module_has_a_layer():
    missing = sorted(m for m in MODULES if m != "jaxgait" and _layer(m) is None)
    assert not missing, f"modules outside the declared layers (add them to LAYERS): {missing}"


@pytest.mark.parametrize("mod", sorted(m for m in MODULES if m != "jaxgait"))
def test_no_import_from_a_layer_above(mod):
    up = sorted(t for t in GRAPH[mod] if (_layer(t) or 0) > (_layer(mod) or 0))
    assert not up, f"{mod} (layer {_layer(mod)}) imports from layers above it: " + ", ".join(
        f"{t} (layer {_layer(t)})" for t in up
    )


def _find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    colour, stack = {}, []

    def visit(n):
        colour[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if colour.get(m) == 1:
                return stack[stack.index(m) :] + [m]
            if colour.get(m) is None:
                found = visit(m)
                if found:
                    return found
        stack.pop()
        colour[n] = 2
        return None

    for n in sorted(graph):
        if colour.get(n) is None:
            found = visit(n)
            if found:
                return found
    return None


def test_no_import_cycle():
    cycle = _find_cycle(GRAPH)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_checks_can_fail():
    """The cycle finder and the layer rule see a planted violation."""
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _find_cycle({"a": {"b"}, "b": set()}) is None
    assert _layer("jaxgait.sim.step") > _layer("jaxgait.control.fbl")
    assert "jaxgait.control.fbl" in GRAPH["jaxgait.sim.model"] or (
        "jaxgait.control.interface" in GRAPH["jaxgait.sim.model"]
    )
