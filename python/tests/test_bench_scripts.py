"""bench/suite_table.py: the tables of docs/performance.md from `fathom bench --json` runs."""
import json
import subprocess
import sys

from conftest import ROOT


def bench_json(path, threads, median, skip=True):
    run = {"scene": "data/lidc2.nrrd", "width": 512, "height": 512, "step": 0.5, "integrator": "alpha",
           "preset": "ct-bone", "threads": threads, "skip_empty": skip, "median_seconds": median,
           "segments_per_second": 1e8 / median, "pixels_per_second": 512 * 512 / median, "setup_seconds": 0.01,
           "peak_rss_bytes": 36e6, "cpu": "test CPU", "hardware_threads": 2}
    path.write_text(json.dumps(run))
    return str(path)


def table(*paths):
    out = subprocess.run([sys.executable, str(ROOT / "bench" / "suite_table.py"), *paths], check=True,
                         capture_output=True, text=True)
    return out.stdout


def test_one_pass_gives_a_row_per_run_and_the_thread_scaling(tmp_path):
    text = table(bench_json(tmp_path / "t2.json", 2, 0.100), bench_json(tmp_path / "t1.json", 1, 0.190))
    rows = [line for line in text.splitlines() if line.startswith("| lidc2.nrrd |")]
    assert len(rows) == 2
    assert "| 0.190 s | 0.100 s | 1.90× |" in text
    assert "passes" not in text


def test_passes_are_merged_keeping_the_shortest_median(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    paths = [bench_json(tmp_path / "a" / "t2.json", 2, 0.150),  # a burst of noise in pass a
             bench_json(tmp_path / "a" / "t1.json", 1, 0.190),
             bench_json(tmp_path / "b" / "t2.json", 2, 0.100),
             bench_json(tmp_path / "b" / "t1.json", 1, 0.200),
             bench_json(tmp_path / "b" / "off.json", 2, 0.300, skip=False)]
    text = table(*paths)
    assert "the shortest median frame of up to 2 passes" in text
    rows = [line for line in text.splitlines() if line.startswith("| lidc2.nrrd |")]
    assert len(rows) == 3  # one per configuration, not per file
    assert "| 0.190 s | 0.100 s | 1.90× |" in text  # scaling from the kept rows
    assert "| 0.300 s | 0.100 s | 3.00× |" in text  # skipping likewise
    assert "0.150 s" not in text


def fake_fathom(path, seconds):
    """A stand-in for `fathom` whose `bench --json FILE` reports the next of `seconds`
    and appends its name to calls.log beside it."""
    state = path.with_suffix(".n")
    log = path.parent / "calls.log"
    path.write_text(f"""#!{sys.executable}
import json, sys
times = {seconds!r}
n = int(open({str(state)!r}).read()) if __import__("os").path.exists({str(state)!r}) else 0
open({str(state)!r}, "w").write(str(n + 1))
open({str(log)!r}, "a").write({path.name!r} + "\\n")
assert sys.argv[1] == "bench" and "--preset" in sys.argv
json.dump({{"median_seconds": times[n]}}, open(sys.argv[sys.argv.index("--json") + 1], "w"))
""")
    path.chmod(0o755)
    return str(path)


def ab(*args):
    return subprocess.run([sys.executable, str(ROOT / "bench" / "ab.py"), *args], capture_output=True, text=True)


def test_ab_alternates_the_builds_and_takes_the_median_ratio(tmp_path):
    base = fake_fathom(tmp_path / "base", [0.120, 0.130, 0.119])
    new = fake_fathom(tmp_path / "new", [0.100, 0.100, 0.119])
    out = ab(base, new, "--pairs", "3", "--", "--volume", "v.nrrd", "--preset", "ct-bone")
    assert out.returncode == 0, out.stderr
    assert "base 0.120 / 0.130 / 0.119 s" in out.stdout
    assert "new  0.100 / 0.100 / 0.119 s" in out.stdout
    assert "per pair 1.20 / 1.30 / 1.00; median 1.20x" in out.stdout
    assert (tmp_path / "calls.log").read_text().split() == ["base", "new"] * 3


def test_ab_reports_a_failing_build_and_needs_the_separator(tmp_path):
    base = fake_fathom(tmp_path / "base", [0.1])
    broken = tmp_path / "broken"
    broken.write_text("#!/bin/sh\necho 'fathom: bench: no such volume' >&2\nexit 1\n")
    broken.chmod(0o755)
    out = ab(base, str(broken), "--", "--preset", "ct-bone")
    assert out.returncode != 0
    assert "no such volume" in out.stderr
    assert ab(base, base, "--preset", "ct-bone").returncode != 0


def fake_threaded_fathom(path, seconds):
    """A stand-in for `fathom` whose `bench --threads T --json FILE` reports seconds[T]'s
    next value and appends T to calls.log beside it."""
    log = path.parent / "calls.log"
    path.write_text(f"""#!{sys.executable}
import json, os, sys
times = {seconds!r}
t = sys.argv[sys.argv.index("--threads") + 1]
state = {str(path)!r} + "." + t
n = int(open(state).read()) if os.path.exists(state) else 0
open(state, "w").write(str(n + 1))
open({str(log)!r}, "a").write(t + "\\n")
assert sys.argv[1] == "bench" and "--preset" in sys.argv
json.dump({{"median_seconds": times[t][n]}}, open(sys.argv[sys.argv.index("--json") + 1], "w"))
""")
    path.chmod(0o755)
    return str(path)


def scaling(*args):
    return subprocess.run([sys.executable, str(ROOT / "bench" / "scaling.py"), *args], capture_output=True,
                          text=True)


def test_scaling_alternates_the_thread_counts_and_takes_the_median_speed_up(tmp_path):
    fathom = fake_threaded_fathom(tmp_path / "fathom", {"1": [0.190, 0.300, 0.200], "2": [0.100, 0.150, 0.125]})
    out = scaling("--fathom", fathom, "--pairs", "3", "--", "--volume", "v.nrrd", "--preset", "ct-bone")
    assert out.returncode == 0, out.stderr
    assert "1 thread  0.190 / 0.300 / 0.200 s" in out.stdout
    assert "2 threads 0.100 / 0.150 / 0.125 s" in out.stdout
    assert "per pair 1.90 / 2.00 / 1.60; median 1.90x" in out.stdout
    assert (tmp_path / "calls.log").read_text().split() == ["1", "2"] * 3


def test_scaling_takes_other_thread_counts(tmp_path):
    fathom = fake_threaded_fathom(tmp_path / "fathom", {"2": [0.2], "4": [0.1]})
    out = scaling("--fathom", fathom, "--pairs", "1", "--threads", "2,4", "--", "--preset", "ct-bone")
    assert out.returncode == 0, out.stderr
    assert "per pair 2.00; median 2.00x" in out.stdout


def test_scaling_refuses_its_own_threads_in_the_bench_arguments_and_bad_counts(tmp_path):
    fathom = fake_threaded_fathom(tmp_path / "fathom", {"1": [0.2], "2": [0.1]})
    out = scaling("--fathom", fathom, "--", "--preset", "ct-bone", "--threads", "2")
    assert out.returncode != 0 and "leave it out" in out.stderr
    for bad in ("2,1", "1", "one,two", "0,2"):
        out = scaling("--fathom", fathom, "--threads", bad, "--", "--preset", "ct-bone")
        assert out.returncode != 0 and "--threads wants" in out.stderr, bad
    assert not (tmp_path / "calls.log").exists()
    assert scaling("--fathom", fathom, "--preset", "ct-bone").returncode != 0
