"""Type-check the package with mypy, as it is installed: ``python .ci/typecheck.py [extra mypy arguments]``.

The package-dir mapping of ``pyproject.toml`` puts ``envs/`` at ``fawtgym.envs`` (and ``observers/``,
``agents/``, ``train/``, ``eval/`` alike), so mypy cannot check the source folders as they lie. This script
builds the installed layout as a tree of symbolic links under ``.mypy_cache/tree`` (read from
``[tool.setuptools.package-dir]``, nothing copied or built), runs ``mypy -p fawtgym`` on it with the
``[tool.mypy]`` settings of ``pyproject.toml``, and prints the errors with the repository's own paths
(``envs/hover_env.py:12: error: ...``). The exit status is mypy's (0: clean, 1: errors, 2: crash/usage).
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

try:
    import tomllib
except ImportError:  # Python 3.10: mypy depends on tomli there
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
TREE = ROOT / ".mypy_cache" / "tree"


def package_dirs() -> dict[str, Path]:
    """Dotted package name -> source folder, from ``[tool.setuptools.package-dir]``."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    return {name: ROOT / folder for name, folder in cfg.items()}


def build_tree() -> dict[Path, Path]:
    """Lay out ``TREE/fawtgym/...`` as symlinks to the sources; return {link dir: source dir} for path mapping."""
    if TREE.exists():
        shutil.rmtree(TREE)
    dirs = package_dirs()
    mapping: dict[Path, Path] = {}
    # shortest names first: "fawtgym" is a real folder in the tree, its mapped subpackages are links inside it
    for name in sorted(dirs, key=lambda n: n.count(".")):
        link = TREE.joinpath(*name.split("."))
        source = dirs[name]
        if not source.is_dir():
            raise SystemExit(f"typecheck.py: package-dir {name!r} -> {source} is not a folder")
        if name.count(".") == 0:
            link.mkdir(parents=True)
            for child in source.iterdir():
                if child.name != "__pycache__" and not (link / child.name).exists():
                    (link / child.name).symlink_to(child, target_is_directory=child.is_dir())
        else:
            if link.exists() or link.is_symlink():
                link.unlink()
            link.symlink_to(source, target_is_directory=True)
        mapping[link] = source
    return mapping


def to_repo_path(line: str, mapping: dict[Path, Path]) -> str:
    """Rewrite the tree path that starts a mypy line (``fawtgym/envs/x.py:3: ...``) to the repository's path."""
    if not line.startswith("fawtgym/"):
        return line
    path, sep, rest = line.partition(":")
    full = TREE / path
    for link in sorted(mapping, key=lambda p: len(p.parts), reverse=True):
        if full.is_relative_to(link):
            return (mapping[link] / full.relative_to(link)).relative_to(ROOT).as_posix() + sep + rest
    return line


def main(argv: list[str]) -> int:
    from mypy import api

    mapping = build_tree()
    args = ["--config-file", str(ROOT / "pyproject.toml"), "--cache-dir", str(ROOT / ".mypy_cache"),
            "--no-error-summary" if "--no-error-summary" in argv else "--error-summary", "-p", "fawtgym", *argv]
    env_path = os.environ.get("MYPYPATH")
    os.environ["MYPYPATH"] = str(TREE) + (os.pathsep + env_path if env_path else "")
    os.chdir(TREE)  # mypy must not see the repository's own envs/, eval/, ... as top-level packages
    out, err, status = api.run(args)
    for line in out.splitlines():
        print(to_repo_path(line, mapping))
    if err:
        print(err, end="", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
