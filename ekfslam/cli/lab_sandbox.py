"""A sandbox per graded exercise: the student's notebook runs there, and only there.

`Sandbox` starts `ekfslam.cli.lab_producer` inside bubblewrap (``bwrap``, Debian's
``bubblewrap``): a new user, PID, network, IPC and UTS namespace, no capabilities, no network;
a root of its own holding read-only only the system's programs and libraries, the Python
environment, the package as `package_for` left it for this exercise, the seed's public runs, and
a private copy of the one notebook; a size-limited private /tmp, its working folder. Not there:
the submissions, the course (its solutions, its key), the CSV and feedback, HOME, the folder
`lab grade` runs in. Limits on address space, CPU time, file size and processes (`LIMITS`);
``--die-with-parent`` and a PID namespace, so when the grader kills it at its deadline every
process the notebook started dies with it, and none outlives the grading.

`package_for(exercise)` writes the package as the sandbox of that exercise holds it: the modules
the exercise may use (`Exercise.keeps`, with every module they import), each function of
`Exercise.denies` replaced by one that raises `ekfslam.errors.LabForbidden`; the lab's checks
answering yes without judging; every other module a stand-in whose names are
`ekfslam.errors.Forbidden`. So the package's answer to the exercise, and what does the same
work, is absent from the process, not watched: no thread, executor or lazy result reaches it.

Without bubblewrap (`unavailable` says why) the same producer runs as a plain process with the
same limits and the same package (``--unsafe-no-sandbox``): the package's answer is still
absent, but the notebook can read and write whatever the instructor can.
"""

from __future__ import annotations

import ast
import compileall
import contextlib
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from ekfslam.places import seed_runs_dir
from ekfslam.teaching.lab_wire import (
    WireError,
    decode,
    encode,
    parse_source,
    read_frame,
    write_frame,
)
from ekfslam.teaching.verdicts import Exercise, Remote, Unanswered, Wrong

PACKAGE = Path(__file__).resolve().parents[1]
#: what every sandbox keeps: the producer and what it imports
BASE = (
    "ekfslam",
    "ekfslam.errors",
    "ekfslam.geometry",
    "ekfslam.places",
    "ekfslam.cli.lab_producer",
)
#: the lab's checks: in a sandbox each check_* says yes and judges nothing
CHECKS = (
    "ekfslam.teaching.exercises",
    "ekfslam.teaching.map_exercises",
    "ekfslam.analysis.lab_checks",
)
#: address space, CPU seconds, bytes a file may grow to, processes; /tmp's size
LIMITS = {"memory": 4 * 2**30, "file": 64 * 2**20, "processes": 64, "tmp": 256 * 2**20}
#: what the sandbox's root holds of the system, read-only, where it exists
SYSTEM = (
    "/usr",
    "/bin",
    "/sbin",
    "/lib",
    "/lib32",
    "/lib64",
    "/libx32",
    "/etc/ld.so.cache",
    "/etc/ld.so.conf",
    "/etc/ld.so.conf.d",
    "/etc/localtime",
    "/etc/alternatives",
    "/etc/fonts",
)
INSTALL = (
    "install bubblewrap (Debian/Ubuntu: apt install bubblewrap), or grade in the container of "
    "INSTRUCTOR.md"
)


class SandboxFailed(Unanswered):
    """The sandbox could not run the notebook (a dead or hung process, a broken answer)."""


def unavailable() -> str | None:
    """Why no sandbox can be made here, or None when bubblewrap runs."""
    if not sys.platform.startswith("linux"):
        return f"the lab's sandbox is bubblewrap, which needs Linux ({sys.platform} here)"
    bwrap = shutil.which("bwrap")
    if bwrap is None:
        return "bubblewrap (bwrap) is not installed"
    probe = [bwrap, "--ro-bind", "/", "/", "--unshare-all", "--die-with-parent", "true"]
    try:
        done = subprocess.run(probe, capture_output=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as error:
        return f"bubblewrap does not start ({error})"
    if done.returncode != 0:
        why = done.stderr.decode("utf-8", "replace").strip().splitlines()[-1:] or ["?"]
        return f"bubblewrap cannot make namespaces here ({why[0]})"
    return None


# --- the package a sandbox holds -------------------------------------------------------------


def _module_file(name: str) -> Path | None:
    base = PACKAGE.parent.joinpath(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def _imports(name: str) -> set[str]:
    """The package's modules that module `name` imports (anywhere in it, by any form)."""
    path = _module_file(name)
    if path is None:
        return set()
    found = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in _walk_run_time(parse_source(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
                module = f"{base}.{node.module}" if node.module else base
            else:
                module = node.module or ""
            found.add(module)
            found |= {f"{module}.{a.name}" for a in node.names}
    return {m for m in found if m.split(".")[0] == "ekfslam" and _module_file(m)}


def _walk_run_time(tree: ast.AST) -> Iterator[ast.AST]:
    """`ast.walk(tree)` without the ``if TYPE_CHECKING:`` blocks: what they import never runs (the
    facade's names are imported there for the type checker; a sandbox that kept them kept the
    whole filter, alignment and replay, the answers of exercises 3 to 9)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo += node.orelse
            continue
        yield node
        todo += ast.iter_child_nodes(node)


def closure(roots: tuple[str, ...] | list[str]) -> set[str]:
    """`roots`, every module of the package they import, and their parent packages."""
    kept: set[str] = set()
    todo = list(roots)
    while todo:
        name = todo.pop()
        if name in kept or _module_file(name) is None:
            continue
        kept.add(name)
        parts = name.split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts))]
        todo += sorted(_imports(name))
    return kept


def _forbidden_module(name: str, exercise: str) -> str:
    return (
        f'"""{name}: left out while exercise {exercise} is graded."""\n'
        "from ekfslam.errors import Forbidden as _Forbidden\n\n\n"
        "def __getattr__(name):\n"
        "    if name.startswith('__'):\n"
        "        raise AttributeError(name)\n"
        f"    return _Forbidden({name!r} + '.' + name, {exercise!r})\n"
    )


def _checks_module(name: str, exercise: str) -> str:
    return (
        f'"""{name} in a graded sandbox: each check says yes and judges nothing."""\n'
        "from ekfslam.errors import Forbidden as _Forbidden\n\n\n"
        "def _yes(*args, **kwargs):\n"
        "    return True\n\n\n"
        "def __getattr__(name):\n"
        "    if name.startswith('check_'):\n"
        "        return _yes\n"
        "    if name.startswith('__'):\n"
        "        raise AttributeError(name)\n"
        f"    return _Forbidden({name!r} + '.' + name, {exercise!r})\n"
    )


def _deny(source: str, module: str, qualnames: list[str], exercise: str) -> str:
    """`source` with the body of each function `qualnames` (``f``, ``Class.method``) raising."""
    tree = parse_source(source)
    left = set(qualnames)

    def visit(body: list, prefix: str) -> None:
        for node in body:
            if isinstance(node, ast.ClassDef):
                visit(node.body, f"{prefix}{node.name}.")
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                qualname = prefix + node.name
                if qualname in left:
                    left.discard(qualname)
                    message = (
                        f"the package's {module}.{qualname} is not available while exercise "
                        f"{exercise} is graded: write it yourself"
                    )
                    raise_ = parse_source(
                        f"raise __import__('ekfslam.errors').errors.LabForbidden({message!r})"
                    ).body
                    node.body = raise_
                    node.decorator_list = [
                        d for d in node.decorator_list if "cache" not in ast.unparse(d)
                    ]

    visit(tree.body, "")
    if left:
        raise ValueError(f"{module} has no {', '.join(sorted(left))} to deny")
    return ast.unparse(tree) + "\n"


def package_for(exercise: Exercise, root: Path, *, sandboxed: bool = True) -> Path:
    """Write the package as exercise `exercise`'s sandbox holds it under `root`; returns the
    folder standing for the package (``root/ekfslam``), compiled so no sandbox compiles it."""
    kept = closure([*BASE, "ekfslam.teaching.lab_wire", *exercise.keeps])
    denied: dict[str, list[str]] = {}
    for entry in exercise.denies:
        module, _, qualname = entry.partition(":")
        denied.setdefault(module, []).append(qualname)
    unknown = set(denied) - kept
    if unknown:
        raise ValueError(
            f"exercise {exercise.number} denies in modules it does not keep: {unknown}"
        )
    target = root / "ekfslam"
    for path in PACKAGE.rglob("*"):
        rel = path.relative_to(PACKAGE)
        if "__pycache__" in rel.parts or path.is_dir():
            continue
        out = target / rel
        out.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix != ".py":
            shutil.copyfile(path, out)
            continue
        parts = ("ekfslam", *rel.with_suffix("").parts)
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        if name in CHECKS:
            out.write_text(_checks_module(name, exercise.number), encoding="utf-8")
        elif name in kept:
            source = path.read_text(encoding="utf-8")
            if name in denied:
                source = _deny(source, name, denied[name], exercise.number)
            out.write_text(source, encoding="utf-8")
        else:
            out.write_text(_forbidden_module(name, exercise.number), encoding="utf-8")
    runs = seed_runs()
    if runs is not None and not (target / "runs").exists():
        if sandboxed:
            (target / "runs").mkdir()  # where the sandbox binds them
        else:
            (target / "runs").symlink_to(runs)
    compileall.compile_dir(str(target), quiet=2, workers=1)
    return target


def seed_runs() -> Path | None:
    """The seed's runs the notebooks read (public: every release holds them)."""
    installed = PACKAGE / "runs"
    if installed.is_dir():
        return None  # inside the package: its copy holds them
    runs = seed_runs_dir()
    return runs if runs is not None and runs.is_dir() else None


# --- one exercise's sandbox ------------------------------------------------------------------


def _limits(cpu_seconds: float) -> None:
    """Set in the sandbox's first process before it starts (and so in all it starts)."""
    for which, value in (
        (resource.RLIMIT_AS, LIMITS["memory"]),
        (resource.RLIMIT_FSIZE, LIMITS["file"]),
        (resource.RLIMIT_NPROC, LIMITS["processes"]),
        (resource.RLIMIT_CORE, 0),
        (resource.RLIMIT_CPU, int(cpu_seconds) + 1),
    ):
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(which, (value, value))


ENVIRONMENT = {
    "PATH": "/usr/local/bin:/usr/bin:/bin",
    "HOME": "/tmp/home",
    "LANG": "C.UTF-8",
    "MPLBACKEND": "Agg",
    "MPLCONFIGDIR": "/tmp/home/matplotlib",
    "IPYTHONDIR": "/tmp/home/ipython",
    "NUMBA_CACHE_DIR": "/tmp/home/numba",
    "OPENBLAS_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "PYTHONDONTWRITEBYTECODE": "1",
    "PYTHONHASHSEED": "0",
}


def _bwrap(package: Path, notebook: Path, runs: Path | None, fds: tuple[int, int]) -> list[str]:
    argv = [shutil.which("bwrap") or "bwrap"]
    for path in SYSTEM:
        if os.path.lexists(path):
            argv += ["--ro-bind", path, path]
    work = "/tmp/lab"
    argv += ["--proc", "/proc", "--dev", "/dev"]
    argv += ["--size", str(LIMITS["tmp"]), "--tmpfs", "/tmp", "--dir", "/tmp/home", "--dir", work]
    # the environment after the private /tmp: a clone (and its venv) under /tmp stays visible
    for prefix in sorted({sys.base_prefix, sys.prefix, sys.exec_prefix}):
        if not prefix.startswith("/usr"):
            argv += ["--ro-bind", prefix, prefix]
    python = Path(sys.executable)
    if not str(python).startswith(("/usr", sys.prefix, sys.base_prefix)):
        argv += ["--ro-bind", str(python.parent), str(python.parent)]
    argv += ["--ro-bind", str(package), str(PACKAGE)]  # the sandbox's package, where it is found
    if runs is not None:  # the seed's runs, where `ekfslam.places.seed_run` finds them
        argv += ["--ro-bind", str(runs), str(PACKAGE / "runs")]
        argv += ["--ro-bind", str(runs), f"{work}/data/runs"]
    argv += ["--ro-bind", str(notebook), f"{work}/{notebook.name}", "--chdir", work]
    argv += ["--unshare-all", "--uid", "65534", "--gid", "65534", "--hostname", "lab"]
    argv += ["--die-with-parent", "--new-session", "--cap-drop", "ALL", "--clearenv"]
    for key, value in ENVIRONMENT.items():
        argv += ["--setenv", key, value]
    argv += [sys.executable, "-I", "-m", "ekfslam.cli.lab_producer", *map(str, fds)]
    return argv


def read_answer(answer: object) -> dict:
    """The notebook process's answer to a call, as `Remote.invoke` returns it: {"result"} (the
    value decoded; one that does not decode is the student's "unreadable result") or {"raised",
    "message", "forbidden"}, with "mutated" the indexes of inputs changed in place."""
    if not isinstance(answer, dict):
        raise SandboxFailed("the notebook's process answered nonsense")
    if "result" in answer:
        try:
            answer["result"] = decode(answer["result"])
        except (WireError, ValueError, TypeError) as error:
            answer = {"raised": "an unreadable result", "message": str(error)[:200]}
    mutated = answer.get("mutated", [])
    answer["mutated"] = (
        [i for i in mutated if isinstance(i, int)] if isinstance(mutated, list) else []
    )
    return answer


class Sandbox:
    """One exercise's producer for one student's notebook: start it with `open`, then `call`
    the student's function, `watch`/`watched` a notebook function, and `close` (or leave the
    ``with`` block): the whole process tree is killed then, and at the deadline."""

    def __init__(
        self,
        package: Path,
        notebook: Path,
        exercise: Exercise,
        stop_at: str,
        timeout: float,
        *,
        sandboxed: bool = True,
        runs: Path | None = None,
    ) -> None:
        self.deadline = time.monotonic() + timeout
        self.exercise = exercise
        self.cpu = 0.0  # CPU seconds the sandbox reported at its close (0: it did not)
        self._private = tempfile.TemporaryDirectory(prefix="ekfslam-sandbox-")
        private = Path(self._private.name)
        self.log = private / "stderr.txt"
        requests_r, self._requests = os.pipe()
        self._answers, answers_w = os.pipe()
        fds = (requests_r, answers_w)
        if sandboxed:
            argv, env, cwd = _bwrap(package, notebook, runs, fds), None, None
        else:
            work = private / "work"
            work.mkdir()
            shutil.copyfile(notebook, work / notebook.name)
            argv = [sys.executable, "-m", "ekfslam.cli.lab_producer", *map(str, fds)]
            env = {**ENVIRONMENT, "HOME": str(private), "PYTHONPATH": str(package.parent)}
            env["MPLCONFIGDIR"] = str(private / "mpl")
            env["IPYTHONDIR"] = str(private / "ipython")
            env["NUMBA_CACHE_DIR"] = str(private / "numba")
            env["PATH"] = os.environ.get("PATH", ENVIRONMENT["PATH"])
            cwd = work
        with self.log.open("wb") as log:
            self.process = subprocess.Popen(
                argv,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=log,
                pass_fds=fds,
                env=env,
                cwd=cwd,
                start_new_session=True,
                preexec_fn=lambda: _limits(timeout),
            )
        os.close(requests_r)
        os.close(answers_w)
        try:
            self._send(
                {"notebook": notebook.name, "stop_at": stop_at, "function": exercise.function}
            )
            ready = self._receive()
            if not isinstance(ready, dict) or not ready.get("ready"):
                why = ready.get("why") if isinstance(ready, dict) else None
                raise SandboxFailed(str(why or "the notebook could not be read"))
        except BaseException:
            self.close()
            raise
        self.defined = bool(ready.get("defined"))
        self.errors = [str(e)[:300] for e in ready.get("errors", [])][:20]

    def _send(self, message: object) -> None:
        try:
            write_frame(self._requests, message)
        except OSError:
            raise SandboxFailed(self._why("stopped")) from None

    def _receive(self) -> object:
        try:
            return read_frame(self._answers, self.deadline)
        except WireError as error:
            if time.monotonic() >= self.deadline:
                raise SandboxFailed("timeout") from None
            raise SandboxFailed(self._why(str(error))) from None

    def _why(self, what: str) -> str:
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(timeout=2)  # a process that ended on its own says how
        self.kill()
        code = self.process.returncode
        tail = self.log.read_bytes()[-2000:].decode("utf-8", "replace").strip().splitlines()
        if code is not None and code < 0:
            name = signal.Signals(-code).name
            extra = " (its CPU time ran out)" if name == "SIGXCPU" else ""
            return f"the notebook's process was killed by {name}{extra}"
        last = tail[-1] if tail else what
        return f"the notebook's process ended (exit status {code}: {last[:200]})"

    def call(self, args: list) -> dict:
        """The student's function on `args`: {"result": value} or {"raised", "message",
        "forbidden"}, with "mutated" (the indexes of inputs it changed)."""
        self._send({"call": encode(list(args))})
        return read_answer(self._receive())

    def watch(self, name: str) -> bool:
        self._send({"watch": name})
        answer = self._receive()
        return isinstance(answer, dict) and answer.get("watching") is True

    def watched(self) -> int | None:
        self._send({"watched": True})
        answer = self._receive()
        calls = answer.get("calls") if isinstance(answer, dict) else None
        return calls if isinstance(calls, int) else None

    def kill(self) -> None:
        if self.process.poll() is None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.process.pid, signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(timeout=10)

    def close(self) -> None:
        with contextlib.suppress(OSError, WireError):
            write_frame(self._requests, {"bye": True})
            said = read_frame(self._answers, min(self.deadline, time.monotonic() + 2))
            cpu = said.get("cpu") if isinstance(said, dict) else None
            if isinstance(cpu, float) and 0 <= cpu < 1e6:
                self.cpu = cpu  # as the sandbox reports it: a timing, never a grade
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(timeout=2)  # let it end on its own (it has said bye); then no mercy
        self.kill()
        for fd in (self._requests, self._answers):
            with contextlib.suppress(OSError):
                os.close(fd)
        if os.environ.get("EKFSLAM_LAB_KEEP_SANDBOX_LOG"):
            print(self.log.read_text("utf-8", "replace")[-3000:], file=sys.stderr)
        self._private.cleanup()

    def __enter__(self) -> Sandbox:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SandboxAnswer(Remote):
    """The student's function of one exercise, as the judges call it: in `sandbox`."""

    def __init__(self, sandbox: Sandbox, differentiated: bool) -> None:
        self.sandbox, self.differentiated = sandbox, differentiated

    def invoke(self, args: list) -> dict:
        return self.sandbox.call(args)

    @contextlib.contextmanager
    def session(self, exercise: Exercise):  # type: ignore[override]
        name = exercise.watches
        if name is None or not self.sandbox.watch(name):
            yield
            return
        yield
        if self.sandbox.watched() == 0:
            raise Wrong(
                f"your {exercise.function} does not call your {name} of the exercise before it."
            )
