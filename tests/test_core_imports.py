"""The package's layers: core imports nothing else of fawtgym; importing the env loads no observer."""

import subprocess
import sys
from pathlib import Path

import pytest

CORE = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "fawtgym" / "core").glob("*.py")
              if p.stem != "__init__")


def _loaded(statement: str) -> list[str]:
    code = f"import sys\n{statement}\nprint(' '.join(sorted(m for m in sys.modules if m.startswith('fawtgym'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return out.split()


@pytest.mark.parametrize("module", CORE)
def test_core_imports_nothing_else_of_the_package(module: str) -> None:
    loaded = _loaded(f"import fawtgym.core.{module}")
    assert [m for m in loaded if not m.startswith(("fawtgym.core", "fawtgym._")) and m != "fawtgym"] == []


def test_importing_the_env_loads_no_observer() -> None:
    loaded = _loaded("import fawtgym.envs.hover_env, fawtgym.envs.hover_batch_env")
    assert [m for m in loaded if m.startswith("fawtgym.observers")] == []
