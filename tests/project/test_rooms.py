"""The rooms import one way, the physics loads without Gymnasium, and the env registers in any import order.

Rooms, lowest first: util < core < physics < task < envs, reference, validation, examples
(siblings: none imports another) < guidance < evaluation < the command line; the
learning agents (``rventry_agents``) sit on top and the library never imports them. The check
reads every ``import`` statement, including those inside functions.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RANK = {
    "util": 0, "core": 1, "physics": 2, "task": 3,
    "envs": 4, "reference": 4, "validation": 4, "examples": 4,
    "guidance": 5, "evaluation": 6, "cli": 7,
}  # fmt: skip
SIBLINGS = {"envs", "reference", "validation", "examples"}


def _room(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "rventry_agents":
        return "agents"
    if parts[0] != "rventry_env" or len(parts) < 2:
        return None
    return parts[1]


def _imports(path: Path, package: str) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text())
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the importing package
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append((node.lineno, mod))
            out += [(node.lineno, f"{mod}.{a.name}") for a in node.names]  # `from rventry_env import envs`
    return out


def _violations() -> list[str]:
    bad = []
    for path in sorted((ROOT / "rventry_env").rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        module = ".".join(rel.parts)
        if module == "rventry_env.__init__":
            continue  # registers the env when Gymnasium loads: the package itself, not a room
        room = _room(module)
        package = module.rsplit(".", 1)[0] if path.name != "__init__.py" else module.rsplit(".", 1)[0]
        for line, target in _imports(path, package):
            troom = _room(target)
            if troom is None or troom == room:
                continue
            where = f"{rel}.py:{line} imports {target}"
            if troom == "agents":
                bad.append(f"{where}: the library must not import the learning agents")
            elif troom not in RANK:
                continue  # rventry_env.__version__ and the like
            elif RANK[troom] > RANK[room]:
                bad.append(f"{where}: {room} may not import the higher room {troom}")
            elif troom in SIBLINGS and room in SIBLINGS:
                bad.append(f"{where}: sibling rooms {room} and {troom} must not import each other")
    return bad


def _module_graph() -> dict[str, set[str]]:
    """Module -> the package modules it imports, anywhere in its body (a function-level import counts)."""
    paths = {}
    for path in (ROOT / "rventry_env").rglob("*.py"):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        paths[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path

    def resolve(name: str) -> str | None:
        while name and name not in paths:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for module, path in paths.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        targets = {resolve(t) for _, t in _imports(path, package) if t.startswith("rventry_env")}
        graph[module] = {t for t in targets if t and t != module}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles: each strongly connected set of two or more modules (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_module_imports_itself_back_through_others_within_or_across_rooms():
    assert _circles(_module_graph()) == []


def test_the_circle_check_catches_a_planted_circle_within_a_room(tmp_path, monkeypatch):
    """The check itself can fail: two env modules importing each other (one inside a function) are found."""
    envs = tmp_path / "rventry_env" / "envs"
    envs.mkdir(parents=True)
    (tmp_path / "rventry_env" / "__init__.py").write_text("")
    (envs / "__init__.py").write_text("")
    (envs / "a.py").write_text("from rventry_env.envs.b import g\n")
    (envs / "b.py").write_text("def g():\n    from rventry_env.envs import a\n")
    (envs / "c.py").write_text("from rventry_env.envs import a\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert _circles(_module_graph()) == [["rventry_env.envs.a", "rventry_env.envs.b"]]


def test_rooms_import_one_way():
    assert _violations() == []


def test_the_room_check_catches_an_upward_import(tmp_path, monkeypatch):
    """The check itself can fail: a physics module importing the envs is reported."""
    fake = tmp_path / "rventry_env" / "physics"
    fake.mkdir(parents=True)
    (fake / "bad.py").write_text("def f():\n    from rventry_env.task import EntryTask\n")
    (tmp_path / "rventry_env" / "task").mkdir()
    (tmp_path / "rventry_env" / "task" / "worst.py").write_text("from rventry_env.envs.reward import RewardWeights\n")
    (tmp_path / "rventry_env" / "guidance").mkdir()
    (tmp_path / "rventry_env" / "guidance" / "worse.py").write_text("import rventry_agents.train\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    found = _violations()
    assert any("physics may not import the higher room task" in v for v in found)
    assert any("task may not import the higher room envs" in v for v in found)
    assert any("must not import the learning agents" in v for v in found)


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)


BLOCK_GYMNASIUM = """
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name == "gymnasium" or name.startswith("gymnasium."):
            raise ImportError("gymnasium is blocked in this test")
sys.meta_path.insert(0, Block())
"""


@pytest.mark.parametrize("module", ["rventry_env", "rventry_env.core", "rventry_env.physics", "rventry_env.task",
                                    "rventry_env.reference", "rventry_env.validation.replay.record_replay",
                                    "rventry_env.guidance", "rventry_env.guidance.estimation",
                                    "rventry_env.guidance.replanning", "rventry_env.guidance.tvlqr"])
def test_the_physics_imports_without_gymnasium(module):
    res = _run(BLOCK_GYMNASIUM + f"import {module}\nassert 'gymnasium' not in sys.modules\nprint('ok')")
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"


def test_blocking_really_blocks():
    res = _run(BLOCK_GYMNASIUM + "import rventry_env.envs")
    assert res.returncode != 0 and "gymnasium is blocked" in res.stderr


@pytest.mark.parametrize("order", [
    "import rventry_env\nimport gymnasium as gym",
    "import gymnasium as gym\nimport rventry_env",
    "import gymnasium as gym\nimport rventry_env.core",
])
def test_the_env_registers_in_either_import_order(order):
    res = _run(order + "\nenv = gym.make('RvEntry-v0')\nobs, _ = env.reset(seed=0)\nprint(obs.shape)")
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "(26,)"


def test_the_env_is_not_registered_without_this_package():
    res = _run("import gymnasium as gym\nprint('RvEntry-v0' in gym.registry)")
    assert res.stdout.strip() == "False"


def test_the_thread_limit_is_set_before_numpy_loads():
    """conftest.py sets OMP_NUM_THREADS; it only works if nothing imported NumPy first."""
    import conftest

    assert not conftest.NUMPY_LOADED_BEFORE_CONFTEST


def test_importing_the_package_changes_no_process_setting():
    """XLA's flags, JAX's x64 switch and glibc's allocator are left alone by every import and by building
    a large vector env; the `rventry` command sets what it wants when it starts."""
    pytest.importorskip("jax")
    code = """
import os, sys
before = os.environ.get("XLA_FLAGS")
import rventry_env, rventry_env.envs.jax_vector, rventry_env.envs.jax_stepper, rventry_env.envs.functional, rventry_env.cli
import jax
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.envs import allocator
RvEntryVectorEnv(2048)
assert os.environ.get("XLA_FLAGS") == before, os.environ.get("XLA_FLAGS")
assert not jax.config.jax_enable_x64
assert not allocator._done
print("ok")
"""
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_ENABLE_X64")}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"


NAME_COMPARISON = re.compile(r"\bns\.name\s*[!=]=|[!=]=\s*ns\.name\b")


def test_no_caller_chooses_a_path_by_the_namespace_name(tmp_path, monkeypatch):
    """Callers test the backend's capabilities (array, concrete, symbolic), never its name; the check
    itself fails on a planted comparison."""

    def offenders(root):
        return [str(p.relative_to(root)) for p in sorted((root / "rventry_env").rglob("*.py"))
                if NAME_COMPARISON.search(p.read_text())]  # fmt: skip

    assert offenders(ROOT) == []
    planted = tmp_path / "rventry_env" / "physics"
    planted.mkdir(parents=True)
    (planted / "bad.py").write_text('def f(x, ns):\n    return x if ns.name == "numpy" else -x\n')
    assert offenders(tmp_path) == ["rventry_env/physics/bad.py"]
