"""The warm-up (slitcli.warmup): kernel inventory, compile announcements, and that a
detect run after the warm-up compiles nothing."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from slitcli.warmup import JOBS, compile_bytecode, kernel_inventory, warm_up

ROOT = Path(__file__).resolve().parent.parent
NOTICE = "slitcli: compiling numba kernels"


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))


def test_inventory_reads_every_decorator_form_and_skips_inlined(tmp_path):
    pkg = tmp_path / "pkg"
    _write(pkg / "__init__.py", "")
    _write(pkg / "a.py", """
        import numba
        import numba as nb
        from numba import jit, njit

        @njit
        def bare(x):
            return x

        @njit(cache=True, nogil=True)
        def called(x):
            return x

        @nb.njit(cache=True)
        def aliased(x):
            return x

        @numba.jit(nopython=True)
        def jitted(x):
            return x

        @jit
        def plain_jit(x):
            return x

        @njit(cache=True, inline="always")
        def inlined(x):
            return x

        def python(x):
            return x

        class Holder:
            @staticmethod
            @njit
            def method(x):
                return x
        """)
    _write(pkg / "sub" / "b.py", """
        from numba import njit

        def factory():
            @njit
            def inner(x):
                return x
            return inner
        """)
    _write(pkg / "c.py", "def no_kernels():\n    return 1\n")
    assert kernel_inventory(pkg) == (
        "pkg.a.Holder.method", "pkg.a.aliased", "pkg.a.bare", "pkg.a.called",
        "pkg.a.jitted", "pkg.a.plain_jit", "pkg.sub.b.factory.<locals>.inner")


def test_inventory_matches_the_dispatchers_the_package_defines():
    """The source scan and the imported modules agree: every module-level numba
    dispatcher of slitcli (bar inline='always' ones) is in the inventory, and every
    inventory name is such a dispatcher."""
    import importlib

    from numba.core.dispatcher import Dispatcher

    inventory = kernel_inventory()
    modules = {name.rpartition(".")[0] for name in inventory}
    found = set()
    for p in sorted((ROOT / "slitcli").rglob("*.py")):
        if "numba" not in p.read_text():
            continue
        parts = p.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        module = importlib.import_module(name)
        for value in vars(module).values():
            if (isinstance(value, Dispatcher) and value.py_func.__module__ == name
                    and value.targetoptions.get("inline", "never") != "always"):
                found.add(f"{name}.{value.py_func.__qualname__}")
    assert found == set(inventory)
    # the SGM kernels (stereo._sgm, _sgm_lanes, _bracket) are the numba ones left
    assert len(inventory) >= 20 and len(modules) >= 3


def _env() -> dict[str, str]:
    """This environment without the flag of a notice already given."""
    return {k: v for k, v in os.environ.items() if k != "SLITCLI_COMPILE_ANNOUNCED"}


def _run(code: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=cwd,
                          capture_output=True, text=True, timeout=600, env=_env())


def test_a_compile_is_announced_once_and_a_cache_hit_not_at_all(tmp_path):
    """A real compile prints one line on stderr however many kernels compile; the next
    process, which loads the same kernels from the cache, prints none."""
    _write(tmp_path / "kern.py", """
        from numba import njit

        @njit(cache=True)
        def twice(x):
            return 2.0 * x

        @njit(cache=True)
        def thrice(x):
            return 3.0 * x
        """)
    code = """
        import sys
        from slitcli.compile_notice import announce_compiles
        announce_compiles(lambda line: print(line, file=sys.stderr))
        import kern
        print(kern.twice(1.5), kern.thrice(2.0), kern.twice(2))
        """
    first = _run(code, tmp_path)
    assert first.returncode == 0, first.stderr
    assert first.stdout.split() == ["3.0", "6.0", "4.0"]
    assert first.stderr.count(NOTICE) == 1
    again = _run(code, tmp_path)
    assert again.returncode == 0, again.stderr
    assert again.stdout.split() == ["3.0", "6.0", "4.0"]
    assert NOTICE not in again.stderr


def test_warm_up_refuses_unknown_jobs_and_no_workers():
    from slitcli.errors import SlitcliError

    with pytest.raises(SlitcliError, match="unknown warm-up job"):
        warm_up(jobs=["render", "nope"])
    with pytest.raises(SlitcliError, match="`workers`"):
        warm_up(workers=0)


def test_every_job_needs_only_known_jobs_before_it():
    order = list(JOBS)
    for name, (_, needs) in JOBS.items():
        assert all(order.index(n) < order.index(name) for n in needs), name


def test_every_job_runs_and_detect_after_the_warm_up_compiles_nothing(tmp_path):
    """Every job runs against the library as it stands (a job calls entry points such as
    run_laser and StereoParams fields: one that no longer fits fails here by name, while
    the set-up only reports it). Then the must-show's mechanism: after the warm-up
    (make's set-up has run it; here it mostly loads the cache), `slitcli detect` on
    another scene's frame (the bundled corridor sequence, not the warm-up's scene) finds
    every kernel it calls in the cache: no compile is announced, and bins are ranged."""
    report = warm_up()
    assert report.failed == (), {n: report.jobs[n].error for n in report.failed}
    assert set(report.jobs) == set(JOBS)
    assert set(report.ready) <= set(report.kernels)
    assert len(report.ready) + len(report.not_reached) == len(report.kernels)
    seq = ROOT / "sample_data" / "sequences" / "corridor"
    one = tmp_path / "one"
    for side in ("left", "right"):
        (one / side).mkdir(parents=True)
        shutil.copy(seq / side / "000000.png", one / side / "000000.png")
    shutil.copy(seq / "rig.yaml", one / "rig.yaml")
    (one / "times.csv").write_text("frame,time_s\n0,0\n")
    res = subprocess.run([sys.executable, "-m", "slitcli", "detect", str(one), "-o",
                          str(tmp_path / "out")], capture_output=True, text=True,
                         timeout=600, env=_env())
    assert res.returncode == 0, res.stderr
    assert NOTICE not in res.stderr
    assert "1 frames" in res.stdout
    rows = (tmp_path / "out" / "ranges.csv").read_text().splitlines()
    assert len(rows) > 10


def test_a_failing_job_is_reported_not_raised(tmp_path, monkeypatch):
    """In the worker: the job's exception becomes the result's one-line error."""
    import slitcli.warmup as wu

    def boom(work: Path) -> None:
        raise ValueError(f"no scene in {work.name}\nsecond line")

    monkeypatch.setattr(wu, "JOBS", {"boom": (boom, ())})
    result = wu._run_job("boom", str(tmp_path))
    assert result.name == "boom" and result.compiled == 0
    assert result.error == f"ValueError: no scene in {tmp_path.name}"


@pytest.mark.parametrize("asked", [True, False])
def test_a_worker_announces_only_when_its_parent_asked(tmp_path, asked):
    """A --jobs worker (spawned: no hook inherited) gives the notice when the command
    line that started it installed one, and stays quiet otherwise."""
    _write(tmp_path / "kern_w.py", """
        from numba import njit

        @njit
        def half(x):
            return 0.5 * x
        """)
    env = _env()
    env.pop("SLITCLI_COMPILE_NOTICE", None)
    if asked:
        env["SLITCLI_COMPILE_NOTICE"] = "1"
    res = subprocess.run([sys.executable, "-c", textwrap.dedent("""
        from slitcli.compile_notice import announce_in_worker
        announce_in_worker()
        import kern_w
        print(kern_w.half(3.0))
        """)], cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["1.5"]
    assert res.stderr.count(NOTICE) == (1 if asked else 0)


def test_bytecode_is_written_where_python_would_not(tmp_path):
    """compile_bytecode writes a .pyc per module that Python accepts (its header holds the
    source's modification time and size), and an import with PYTHONDONTWRITEBYTECODE
    then reads it instead of compiling the source."""
    import importlib.util

    pkg = tmp_path / "pkg"
    _write(pkg / "__init__.py", "")
    _write(pkg / "sub" / "__init__.py", "")
    _write(pkg / "sub" / "mod.py", "X = 41 + 1\n")
    assert compile_bytecode(pkg)
    for src in pkg.rglob("*.py"):
        header = Path(importlib.util.cache_from_source(str(src))).read_bytes()[:16]
        st = src.stat()
        assert header[:4] == importlib.util.MAGIC_NUMBER
        assert int.from_bytes(header[8:12], "little") == int(st.st_mtime) & 0xFFFFFFFF
        assert int.from_bytes(header[12:16], "little") == st.st_size & 0xFFFFFFFF
    code = ("import importlib._bootstrap_external as b, sys\n"
            "seen = []\n"
            "orig = b.SourceLoader.source_to_code\n"
            "b.SourceLoader.source_to_code = lambda self, *a, **k: seen.append(a[1]) or "
            "orig(self, *a, **k)\n"
            "import pkg.sub.mod\n"
            "print(pkg.sub.mod.X, len(seen))\n")
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "PYTHONPATH": str(tmp_path)}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["42", "0"]
