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
