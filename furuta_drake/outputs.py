"""Output directories that appear complete or not at all.

A command writes its results into a fresh hidden directory beside the requested one and renames it into place
only when every file is written, so an interrupted or failed run never leaves a directory that looks like a
finished result. A non-empty directory is refused unless ``force`` is given; with ``force`` the old directory is
replaced only once the new results are complete. :func:`versions` is the provenance such a directory records.
"""

from __future__ import annotations

import importlib.metadata
import os
import platform
import secrets
import shutil
import subprocess
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from furuta_drake.errors import ConfigError


def prepare_output_dir(out: str | Path, force: bool = False, protect: Iterable[str | Path] = ()) -> Path:
    """Check that ``out`` may be written (call it before a long computation to fail early); return it.

    Raises ConfigError when ``out`` is a file, when it is a non-empty directory and ``force`` is false, or
    when replacing it would delete the working directory or one of the ``protect`` paths (e.g. the input
    logs).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{out}: exists and is not a directory")
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise ConfigError(f"{out}: cannot create it, {parent} is not a directory")
            break
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise ConfigError(f"{out}: directory is not empty; pass --force to replace it")
        resolved = out.resolve()
        for path in [Path.cwd(), *map(Path, protect)]:
            if path.resolve() == resolved or resolved in path.resolve().parents:
                raise ConfigError(
                    f"{out}: --force would delete {path}, which is inside it; choose another output directory"
                )
    return out


@contextmanager
def atomic_output_dir(out: str | Path, force: bool = False, protect: Iterable[str | Path] = ()) -> Iterator[Path]:
    """Yield an empty staging directory beside ``out``; when the block ends without an exception, move it to
    ``out`` (replacing an old ``out`` only then); on an exception, delete it and leave ``out`` untouched."""
    out = prepare_output_dir(out, force, protect)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = out.parent / f".{out.name}.partial-{os.getpid()}-{secrets.token_hex(4)}"
    staging.mkdir()
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    prepare_output_dir(out, force, protect)  # the check again: something may have written there meanwhile
    if out.is_dir() and any(out.iterdir()):
        old = out.parent / f".{out.name}.old-{os.getpid()}-{secrets.token_hex(4)}"
        os.replace(out, old)
        os.replace(staging, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        if out.is_dir():
            out.rmdir()
        os.replace(staging, out)


def versions() -> dict[str, str]:
    """Versions of this package, of the numerical libraries a result depends on, and of Python."""
    found = {}
    for name in ("furuta-drake", "drake", "numpy", "scipy", "matplotlib"):
        try:
            found[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            found[name] = "not installed"
    found["python"] = platform.python_version()
    commit = _git_commit()
    if commit:
        found["furuta-drake git commit"] = commit
    return found


def _git_commit() -> str | None:
    """The commit of the source tree this package runs from, when it is a git checkout."""
    try:
        result = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=Path(__file__).resolve().parent,
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return result.stdout.strip() if result.returncode == 0 else None
