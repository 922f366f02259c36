"""CasADi functions compiled to C once and cached on disk, loaded with ``casadi.external``.

CasADi generates the C code; the system C compiler (``$CC``, else ``cc``, ``gcc`` or ``clang``)
builds a shared library in the user's cache directory (``$XDG_CACHE_HOME/cpopt``, else
``~/.cache/cpopt``). Generating the code takes CasADi a while, so a library is found without
generating it: an index file named by a hash of the generating source files, the library's name,
the CasADi version and the compiler flags points at the library file, which is itself named by a
hash of its code. Every file is written under a temporary name and moved into place
(``os.replace``), so two processes may build the same library at once and neither reads half a
file. Compiling says so in one line on the ``cpopt`` logger (stderr by default); without a
compiler, or when compiling fails, the functions run interpreted and one line says so. The
compile is a one-time cost of a fresh machine (or a new release), so a time limit does not count
it (:func:`cpopt.runtime.budget.uncounted`): the same file given the same limit solves the same
way on the first run and on the next. A compile that Ctrl-C stops finishes on its own and
fills the cache for the next solve (:func:`_compile`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from .budget import uncounted

FLAGS = ("-O1",)
"""Compiler flags: -O1 compiles the sample library in a third of the time of -O2 and runs it as
fast; -O3 and -march=native were measured no faster (and the latter would not be portable)."""

LOG = logging.getLogger("cpopt")
_SUFFIX = ".dll" if sys.platform == "win32" else ".so"


@dataclass(frozen=True)
class Library:
    """Functions by name, compiled (loaded from ``path``) or interpreted (``path`` None)."""

    functions: dict[str, ca.Function]
    path: Path | None

    @property
    def compiled(self) -> bool:
        """True when the functions run as compiled C code."""
        return self.path is not None


def cache_dir() -> Path:
    """The folder of cpopt's compiled libraries: ``$XDG_CACHE_HOME/cpopt`` or ``~/.cache/cpopt``."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "cpopt"


def compiler() -> str | None:
    """The C compiler to use: ``$CC``, else the first of cc, gcc, clang on the PATH (or None)."""
    wanted = os.environ.get("CC")
    if wanted:
        return shutil.which(wanted)
    return next((p for p in map(shutil.which, ("cc", "gcc", "clang")) if p), None)


def source_key(name: str, sources: Sequence[Path]) -> str:
    """Hash of what determines a library's code: its name, the generating source files, the
    CasADi version and the compiler flags (computed without generating any code)."""
    digest = hashlib.sha256(f"{name}|{ca.__version__}|{' '.join(FLAGS)}".encode())
    for path in sources:
        digest.update(Path(path).read_bytes())
    return digest.hexdigest()[:20]


def _write_atomically(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


DETACHED = (
    "cc=$1 src=$2 out=$3 target=$4 log=$5 dir=$6 entry=$7 index=$8; shift 8; "
    '"$cc" "$@" "$src" -o "$out" -lm 2>"$log" && mv -f "$out" "$target" && '
    'printf "%s" "$entry" >"$dir/index" && mv -f "$dir/index" "$index" && rm -rf "$dir"'
)
"""The compile as a shell command that moves its output and then the index file pointing at
it into place itself (POSIX)."""


def _compile(code: str, target: Path, cc: str, index: Path, entry: str) -> None:
    """Compile C code into the shared library ``target`` (atomically), then write ``entry``
    to the index file ``index`` (atomically).

    On POSIX the compiler runs in a session of its own that moves its output and the index
    into place itself (:data:`DETACHED`), so that a solve stopped while it waits (its time
    limit, Ctrl-C, a parent killing it) leaves the compile to finish: the next solve then
    finds the library instead of compiling it again. (A verification library first needed in
    a search's last second was cut at every run of a 20-s limit, each such solve ending
    without its verification.)
    """
    build = Path(tempfile.mkdtemp(dir=target.parent, prefix=".build-"))
    src, out, log = build / "library.c", build / f"library{_SUFFIX}", build / "compiler.log"
    src.write_text(code)
    flags = [*FLAGS, "-shared", "-fPIC"]
    if os.name != "posix":
        try:
            cmd = [cc, *flags, str(src), "-o", str(out), "-lm"]
            subprocess.run(cmd, check=True, capture_output=True, text=True)
            os.replace(out, target)
            _write_atomically(index, entry.encode())
        finally:
            shutil.rmtree(build, ignore_errors=True)
        return
    args = [cc, str(src), str(out), str(target), str(log), str(build), entry, str(index), *flags]
    process = subprocess.Popen(
        ["sh", "-c", DETACHED, "sh", *args],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # not stopped with this process (Ctrl-C, a killed group)
    )
    if process.wait() != 0:
        message = log.read_text() if log.exists() else ""
        shutil.rmtree(build, ignore_errors=True)
        raise subprocess.CalledProcessError(process.returncode, cc, stderr=message)


def _load(path: Path, names: Sequence[str]) -> dict[str, ca.Function]:
    return {n: ca.external(n, str(path)) for n in names}


def _cached(index: Path, directory: Path) -> Library | None:
    """The library an index file points at, if both are there and it loads."""
    try:
        entry = json.loads(index.read_text())
        path = directory / entry["library"]
        return Library(_load(path, entry["functions"]), path) if path.exists() else None
    except (OSError, ValueError, KeyError, RuntimeError):
        return None


def load_library(
    name: str,
    sources: Sequence[Path],
    build: Callable[[], list[ca.Function]],
    directory: Path | None = None,
) -> Library:
    """The functions ``build()`` returns, compiled and cached (see the module docstring).

    Parameters
    ----------
    name : str
        The library's name (file names start with it), e.g. ``samples-RRR``.
    sources : sequence of Path
        The files whose content determines the generated code.
    build : callable
        Returns the CasADi functions to compile (called only when the cache has no library).
    directory : Path, optional
        The cache folder (default :func:`cache_dir`).

    Returns
    -------
    Library
        Compiled functions, or the interpreted ones when no compiler works.
    """
    directory = cache_dir() if directory is None else Path(directory)
    index = directory / f"{name}-{source_key(name, sources)}.json"
    found = _cached(index, directory)
    if found is not None:
        return found
    cc = compiler()
    if cc is None:
        LOG.warning("cpopt: no C compiler found ($CC, cc, gcc, clang): %s runs interpreted", name)
        functions = build()
        return Library({f.name(): f for f in functions}, None)
    with uncounted():  # generating and compiling: once per machine and release
        return _built(name, build, cc, index, directory)


def _built(
    name: str, build: Callable[[], list[ca.Function]], cc: str, index: Path, directory: Path
) -> Library:
    """The library ``build()`` returns, generated, compiled with ``cc`` and cached (or the
    interpreted functions when compiling fails)."""
    functions = build()
    gen = ca.CodeGenerator(re.sub(r"\W", "_", name) + ".c", {"with_header": False})
    for f in functions:
        gen.add(f)
    code = gen.dump()
    digest = hashlib.sha256(code.encode()).hexdigest()[:20]
    path = directory / f"{name}-casadi{ca.__version__}-{digest}{_SUFFIX}"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        entry = {"library": path.name, "functions": [f.name() for f in functions]}
        if not path.exists():
            # a one-time wait of seconds: say so (the default handler shows warnings only)
            LOG.warning(
                "cpopt: compiling %s once with %s (cached in %s; not counted in a time limit)",
                name,
                cc,
                directory,
            )
            tic = time.perf_counter()
            _compile(code, path, cc, index, json.dumps(entry))
            LOG.info("cpopt: compiled %s in %.1f s", name, time.perf_counter() - tic)
        else:  # compiled by another process, or by a compile whose solve was stopped
            _write_atomically(index, json.dumps(entry).encode())
        return Library(_load(path, entry["functions"]), path)
    except (OSError, subprocess.CalledProcessError, RuntimeError) as err:
        why = getattr(err, "stderr", None) or str(err)
        LOG.warning(
            "cpopt: compiling %s failed (%s): runs interpreted", name, " ".join(why.split())[:200]
        )
        return Library({f.name(): f for f in functions}, None)


__all__ = ["FLAGS", "Library", "cache_dir", "compiler", "load_library", "source_key"]
