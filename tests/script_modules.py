"""The repository's benchmarks/ and studies/ scripts as modules for the tests (they are programs, not a package)."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_script(name: str):
    """``<name>.py`` (``benchmarks/rhs_forms``, ``studies/compare_episodes``), imported as a module."""
    path = ROOT / f"{name}.py"
    spec = importlib.util.spec_from_file_location(Path(name).name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
