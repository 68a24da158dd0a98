"""Import cost of the package face against its floor (numpy + the compiled core).

Each figure is the best of ``--repeats`` fresh interpreters (wall clock inside the child, so
interpreter start-up is excluded); the variants take turns, one interpreter each per round, so
a load that comes and goes on a shared machine hits them alike:

  * floor: ``import numpy`` plus loading ``preisach/_core*.so`` directly (no package code);
  * ``import numpy; import preisach`` (the face: lazy, loads the core and the error types);
  * ``import numpy; import preisach.model`` (the simulator surface);
  * ``import numpy; from preisach import diagnose`` (the heaviest public name, for contrast).

The face's target (issue 18): ``import preisach`` costs no more than the floor + 50 ms.

Run:  python benchmarks/bench_import.py [--repeats N]
"""

from __future__ import annotations

import glob
import importlib.util
import os
import subprocess
import sys

from _bench import available_cores, parser

TARGET_MS = 50.0

_TIMER = """
import time
t0 = time.perf_counter()
{body}
print(time.perf_counter() - t0)
"""

_LOAD_CORE = """
import importlib.util
import numpy
spec = importlib.util.spec_from_file_location("preisach._core", {path!r})
mod = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mod)
"""


def core_path() -> str:
    """Path of the compiled core, found without executing the package's ``__init__``."""
    spec = importlib.util.find_spec("preisach")
    assert spec is not None and spec.submodule_search_locations is not None
    for location in spec.submodule_search_locations:
        hits = glob.glob(os.path.join(location, "_core*.so")) + glob.glob(
            os.path.join(location, "_core*.pyd")
        )
        if hits:
            return hits[0]
    raise SystemExit("preisach._core not found: install the package first (pip install -e .)")


def run_ms(body: str) -> float:
    """Wall time (ms) of ``body`` in a fresh interpreter."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    out = subprocess.run(
        [sys.executable, "-c", _TIMER.format(body=body)],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    ).stdout
    return 1e3 * float(out.strip().splitlines()[-1])


def best_ms(bodies: dict[str, str], repeats: int) -> dict[str, float]:
    """Best wall time (ms) of each body over ``repeats`` rounds, the bodies taking turns."""
    best = dict.fromkeys(bodies, float("inf"))
    for _ in range(repeats):
        for name, body in bodies.items():
            best[name] = min(best[name], run_ms(body))
    return best


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()

    cores = available_cores()
    ms = best_ms(
        {
            "numpy": "import numpy",
            "floor": _LOAD_CORE.format(path=core_path()),
            "face": "import numpy\nimport preisach",
            "model": "import numpy\nimport preisach.model",
            "heavy": "import numpy\nfrom preisach import diagnose",
        },
        args.repeats,
    )
    numpy_ms, floor_ms, face_ms, model_ms, heavy_ms = (
        ms[k] for k in ("numpy", "floor", "face", "model", "heavy")
    )

    print(f"cores obtained: {cores}; best of {args.repeats} fresh interpreters each")
    print(f"  import numpy                          {numpy_ms:8.1f} ms")
    print(f"  numpy + _core (floor)                 {floor_ms:8.1f} ms")
    print(f"  numpy + import preisach               {face_ms:8.1f} ms")
    print(f"  numpy + import preisach.model         {model_ms:8.1f} ms")
    print(f"  numpy + from preisach import diagnose {heavy_ms:8.1f} ms")
    over = face_ms - floor_ms
    verdict = "OK" if over <= TARGET_MS else "OVER TARGET"
    print(f"import preisach - floor = {over:+.1f} ms (target <= {TARGET_MS:.0f} ms): {verdict}")


if __name__ == "__main__":
    main()
