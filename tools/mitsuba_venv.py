"""Mitsuba 3 in a private Python venv, shared by tools/bench and tools/check-mitsuba.

`mitsuba_python(venv)` returns the venv's python, first creating the venv (`python3 -m venv`,
installing Debian's python3-venv with apt-get if that fails) and pip-installing
mitsuba==MITSUBA_VERSION into it when it does not import. That pip install is the only download
the tools make. Failures raise SetupError with a one-line reason; callers print it and exit.
"""

import os
import subprocess
import sys
from pathlib import Path

MITSUBA_VERSION = "3.9.1"


class SetupError(Exception):
    """A peer or package could not be installed; str() is one line saying what and why."""


def _stderr(message):
    print(message, file=sys.stderr, flush=True)


def default_cache():
    """${XDG_CACHE_HOME:-$HOME/.cache}/rt-bench: where the tools keep the venv and generated inputs."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rt-bench"


def default_venv():
    """The venv both tools use unless told otherwise: default_cache()/mitsuba-venv."""
    return default_cache() / "mitsuba-venv"


def sudo_prefix():
    """['sudo'] when not root, else []."""
    return [] if os.geteuid() == 0 else ["sudo"]


def apt_install(package, why, log=_stderr):
    """apt-get install one package, updating the package lists once if the first try fails."""
    log(f"installing {package} with apt-get: {why}")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    install = sudo_prefix() + ["apt-get", "install", "-y", "-q", package]
    if subprocess.run(install, env=env).returncode == 0:
        return
    log(f"updating the apt package lists (apt-get update): the install of {package} failed")
    if subprocess.run(sudo_prefix() + ["apt-get", "update", "-q"], env=env).returncode != 0:
        raise SetupError(f"apt-get update failed, so {package} cannot be installed")
    if subprocess.run(install, env=env).returncode != 0:
        raise SetupError(f"apt-get install {package} failed")


def mitsuba_imports(python):
    """Whether `python` (a path) imports mitsuba at MITSUBA_VERSION."""
    check = [str(python), "-c", f"import mitsuba; assert mitsuba.__version__ == '{MITSUBA_VERSION}'"]
    return Path(python).exists() and subprocess.run(check, capture_output=True).returncode == 0


def mitsuba_python(venv, log=_stderr):
    """The venv's python (a Path), creating the venv and installing mitsuba when missing."""
    venv = Path(venv)
    python = venv / "bin" / "python"
    if mitsuba_imports(python):
        return python
    if not python.exists():
        log(f"creating a Python venv in {venv}: Mitsuba 3 is installed there, outside the system Python")
        venv.parent.mkdir(parents=True, exist_ok=True)
        if subprocess.run([sys.executable, "-m", "venv", str(venv)]).returncode != 0:
            apt_install("python3-venv", "python3 -m venv needs it on Debian", log)
            if subprocess.run(["python3", "-m", "venv", str(venv)]).returncode != 0:
                raise SetupError(f"python3 -m venv {venv} failed")
    log(f"installing mitsuba=={MITSUBA_VERSION} into {venv} with pip")
    pip = [str(python), "-m", "pip", "install", "-q", f"mitsuba=={MITSUBA_VERSION}"]
    if subprocess.run(pip).returncode != 0:
        raise SetupError(f"pip install mitsuba=={MITSUBA_VERSION} into {venv} failed (no network?)")
    if not mitsuba_imports(python):
        raise SetupError(f"mitsuba {MITSUBA_VERSION} does not import in {venv}")
    return python
