"""Run the README's and the docs' ``twin`` command lines in order, as typed, in a fresh directory.

    python -m tests.readme_commands [--workdir DIR]

Every line of a README or docs ``sh`` block that starts with ``twin`` runs as a real process: the
README's tour in one empty directory, then the docs pages, in the order the README links them, in
another (their lines build on each other: ``twin sample lab lab.ifc``, then
``twin import lab.ifc --store lab.store``, ...). What the runner changes, and only this:

- optional parts in brackets (``[--json]``) are left out; a line that still holds a placeholder
  (``IRI``, ``FILE.ttl``, ``a | b``, ``...``) is a synopsis, not a command: it is listed as skipped;
- the README's Zenoh ports (7447, 7450, 7451) become free ports, so that the run does not meet a
  daemon already on the machine: the lines' endpoints (on 127.0.0.1 or 0.0.0.0) are rewritten, and
  each command gets ``--config`` of a file whose ``[zenoh] listen`` is the free port that stands for 7447;
- ``twin serve`` and ``twin router`` run in the background (until a later block starts its own, or the
  end); ``twin watch`` without ``--count`` is stopped with SIGTERM once it printed its first map version, as
  a user stops it; ``oxigraph serve`` runs in the background (its port moved too) when the ``oxigraph``
  binary is installed (the dev extra has it), and ``pip install`` of an installed package is skipped;
  blocks that need any other tool first, or a tool that is not installed, are skipped.

Each command must exit 0, or give the refusal listed for it in ``EXPECTED`` (one line on stderr).
Exits 1 and names the commands that did not.
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
PORTS = (7447, 7450, 7451, 7878)
OTHER_TOOLS = ("pip ", "oxigraph ", "ros2 ", "rerun ", "make ")
PIP_INSTALLED = re.compile(r"^pip install (oxigraph|rerun-sdk\S*)\s*(#.*)?$")
EXPECTED = {
    # the daemon of the README's sequence configures no robots: the refusal the README promises
    "twin storey --robot robot1": "Unknown robot 'robot1'",
}
WATCH_LIMIT_S = 60.0  # a watch that printed nothing by then is stopped and fails

log = logging.getLogger("readme_commands")


@dataclass
class Outcome:
    line: str
    status: str  # "ok", "skipped", "failed"
    detail: str = ""


@dataclass
class Runner:
    workdir: Path
    config: Path
    ports: dict[int, int]
    background: list[subprocess.Popen[str]] = field(default_factory=list)

    def argv(self, line: str) -> list[str]:
        for readme_port, port in self.ports.items():
            for host in ("127.0.0.1", "0.0.0.0"):
                line = line.replace(f"{host}:{readme_port}", f"{host}:{port}")
        words = shlex.split(line)
        return [sys.executable, "-m", "adapters.cli", "--config", str(self.config), *words[1:]]

    def run(self, line: str) -> Outcome:
        words = shlex.split(line)
        command = words[1] if len(words) > 1 else ""
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(ROOT)}
        if command in ("serve", "router"):
            return self.start(line, env)
        if command == "watch" and "--count" not in words:
            return self.watch(line, env)
        r = subprocess.run(
            self.argv(line),
            cwd=self.workdir,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
        return self.judge(line, r.returncode, r.stdout, r.stderr)

    def judge(self, line: str, code: int, out: str, err: str) -> Outcome:
        expected = EXPECTED.get(line)
        if expected is not None:
            ok = code == 1 and expected in err and len(err.strip().splitlines()) == 1
            return Outcome(line, "ok" if ok else "failed", err.strip() if ok else f"exit {code}: {err}{out}")
        if code != 0:
            return Outcome(line, "failed", f"exit {code}: {err.strip()}")
        return Outcome(line, "ok", (out.strip().splitlines() or [""])[-1])

    def start(self, line: str, env: dict[str, str]) -> Outcome:
        process = subprocess.Popen(
            self.argv(line), cwd=self.workdir, env=env, text=True,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        )  # fmt: skip
        assert process.stdout is not None
        deadline = time.monotonic() + 120
        seen: list[str] = []
        while time.monotonic() < deadline:
            text = process.stdout.readline()
            if not text:
                break
            seen.append(text.rstrip())
            if text.startswith(("serving site", "router ")):
                self.background.append(process)
                return Outcome(line, "ok", text.strip())
        process.kill()
        process.wait(timeout=10)
        return Outcome(line, "failed", "did not start: " + " | ".join(seen[-5:]))

    def watch(self, line: str, env: dict[str, str]) -> Outcome:
        process = subprocess.Popen(
            self.argv(line), cwd=self.workdir, env=env, text=True,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        )  # fmt: skip
        assert process.stdout is not None
        limit = threading.Timer(WATCH_LIMIT_S, process.send_signal, (signal.SIGTERM,))
        limit.start()
        first = process.stdout.readline()  # the first map version, or "" when the watch ended
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=30)
        limit.cancel()
        out = first + out
        outcome = self.judge(line, process.returncode, out, err)
        if outcome.status == "ok" and not out.strip():
            return Outcome(line, "failed", "printed no map version")
        return outcome

    def oxigraph(self, line: str) -> Outcome:
        """``oxigraph serve ...`` in the background, once its port answers."""
        binary = shutil.which("oxigraph", path=_tool_path())
        if binary is None:
            return Outcome(line, "skipped", "oxigraph is not installed")
        for readme_port, port in self.ports.items():
            line = line.replace(f"127.0.0.1:{readme_port}", f"127.0.0.1:{port}")
        words = shlex.split(re.sub(r"\s+#.*$", "", line))
        process = subprocess.Popen(
            [binary, *words[1:]], cwd=self.workdir, text=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        )  # fmt: skip
        self.background.append(process)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and process.poll() is None:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.ports[7878])) == 0:
                    return Outcome(line, "ok", "oxigraph serves")
            time.sleep(0.1)
        return Outcome(line, "failed", f"oxigraph did not serve: exit {process.poll()}")

    def stop_background(self) -> list[Outcome]:
        """SIGTERM every daemon and router started; a stop that does not exit 0 is a failed outcome."""
        failed: list[Outcome] = []
        for process in self.background:
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
                try:
                    process.communicate(timeout=30)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.communicate(timeout=10)
            if process.returncode != 0 and "adapters.cli" in process.args:  # twin's own, not oxigraph
                what = " ".join(str(a) for a in process.args[3:])  # type: ignore[index]
                failed.append(Outcome(f"stop of {what}", "failed", f"exit {process.returncode}"))
        self.background.clear()
        return failed


def documents() -> list[Path]:
    """The README, then every docs page in the order the README links them (unlinked pages last)."""
    linked = re.findall(r"\]\(docs/([\w-]+\.md)\)", README.read_text())
    pages = [DOCS / name for name in dict.fromkeys(linked)]
    pages += sorted(p for p in DOCS.glob("*.md") if p not in pages)
    return [README, *pages]


def readme_blocks(text: str) -> list[list[str]]:
    """The README's ``sh`` blocks, each as its lines (continuation lines joined)."""
    blocks = re.findall(r"^```sh\n(.*?)^```", text, re.S | re.M)
    return [block.replace("\\\n", " ").splitlines() for block in blocks]


_PLACEHOLDER = re.compile(r"^[A-Z][A-Z0-9_]*(\.\w+)?$|\.\.\.")


def as_typed(line: str) -> str | None:
    """The command ``line`` of the README without its comment and optional parts; None for a synopsis."""
    line = re.sub(r"\s+#.*$", "", line.strip())
    kept: list[str] = []
    depth = 0
    for word in shlex.split(line):
        if depth > 0 or word.startswith("["):
            depth += word.count("[") - word.count("]")
            continue
        kept.append(word)
    if any(w == "|" or _PLACEHOLDER.search(w) for w in kept) or kept == ["twin", "serve"]:
        return None
    return shlex.join(kept)


def _tool_path() -> str:
    """Where other tools are looked for: the venv's bin (the dev extra's ``oxigraph``), then PATH."""
    return f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def run_readme(workdir: Path, parts: tuple[str, ...] = ("readme", "docs")) -> list[Outcome]:
    """Run every ``twin`` line of the README, then of the docs, in ``workdir`` (empty); each outcome.

    The README's tour runs in ``workdir/readme``, the docs in ``workdir/docs``: each is a reader's
    session from an empty folder (the docs' pages build on each other in the README's link order).
    ``parts`` picks one or both sessions (the suite runs them as two tests, side by side)."""
    ports = {p: free_port() for p in PORTS}
    config = workdir / "readme-run.toml"
    config.write_text(f'[zenoh]\nlisten = ["tcp/127.0.0.1:{ports[7447]}"]\n')
    pages = documents()
    outcomes: list[Outcome] = []
    sessions = {"readme": pages[:1], "docs": pages[1:]}
    for name, docs in ((name, sessions[name]) for name in parts):
        folder = workdir / name
        folder.mkdir()
        runner = Runner(folder, config, ports)
        try:
            blocks = [b for doc in docs for b in readme_blocks(doc.read_text())]
            outcomes += run_blocks(runner, blocks)
        finally:
            outcomes += runner.stop_background()
    return outcomes


def run_blocks(runner: Runner, blocks: list[list[str]]) -> list[Outcome]:
    """Run the ``twin`` lines of ``blocks`` in order with ``runner``; the outcome of each."""
    outcomes: list[Outcome] = []
    for block in blocks:
        lines = [ln for ln in block if ln.strip().startswith("twin ")]
        if not lines:
            continue
        others = [ln.strip() for ln in block if ln.strip().startswith(OTHER_TOOLS)]
        runnable = all(PIP_INSTALLED.match(ln) or ln.startswith("oxigraph serve ") for ln in others)
        if not runnable or (others and shutil.which("oxigraph", path=_tool_path()) is None):
            outcomes += [Outcome(ln.strip(), "skipped", "needs another tool first") for ln in lines]
            continue
        typed = [(ln.strip(), as_typed(ln)) for ln in lines]
        if others or any(t is not None and t.split()[1:2] in (["serve"], ["router"]) for _, t in typed):
            outcomes += runner.stop_background()  # a new topology: the previous daemons (and servers) stop
        outcomes += [runner.oxigraph(ln) for ln in others if ln.startswith("oxigraph serve ")]
        for original, command in typed:
            if command is None:
                outcomes.append(Outcome(original, "skipped", "a synopsis with placeholders"))
                continue
            outcome = runner.run(command)
            log.info("%s %s: %s", outcome.status, command, outcome.detail)
            outcomes.append(outcome)
    return outcomes


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workdir", type=Path, help="an empty directory to run in (default: a temporary one)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if args.workdir is not None:
        args.workdir.mkdir(parents=True, exist_ok=True)
        outcomes = run_readme(args.workdir)
    else:
        with tempfile.TemporaryDirectory(prefix="readme-") as tmp:
            outcomes = run_readme(Path(tmp))
    failed = [o for o in outcomes if o.status == "failed"]
    ran = sum(1 for o in outcomes if o.status == "ok")
    skipped = sum(1 for o in outcomes if o.status == "skipped")
    print(
        f"{ran} README commands ran as typed, {len(failed)} failed, {skipped} skipped (synopses, other tools)"
    )
    for o in failed:
        print(f"FAILED {o.line}\n  {o.detail}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
