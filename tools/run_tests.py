#!/usr/bin/env python3
"""`make test-rust`: the crate's tests, each test in its own process, `--jobs`
at a time, the longest first.

`cargo test` runs its test binaries one after another, and a binary with
one long test keeps one core busy at most; this runner lists every test of
every binary (`--list`), runs each alone (`--exact`), and starts the tests
that took longest last time first (tools/test_durations.json, written by
`--write-durations`), so the two cores stay busy to the end. A test's
output is printed when it ends, whole when it failed. The doc-tests run
last through cargo. Exit status 1 when any test failed, naming each.

The tests share what they render and extract through a disk cache
(tests/common: `SPSLAM_TEST_CACHE`), emptied at the start of each run:
a test in its own process would otherwise redo the frames another test of
its binary has already seen.

Usage: tools/run_tests.py [--jobs N] [--write-durations] [-- CARGO_TEST_ARGS...]
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DURATIONS = ROOT / "tools" / "test_durations.json"
CACHE = ROOT / "target" / "test-cache"


def test_binaries(cargo_args):
    """(binary name, executable) of every test target cargo builds."""
    cmd = ["cargo", "test", "--no-run", "--message-format=json-render-diagnostics", *cargo_args]
    proc = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, text=True)
    if proc.returncode != 0:
        sys.exit(f"error: `{' '.join(cmd)}` failed (exit {proc.returncode}); its messages are above")
    binaries = []
    for line in proc.stdout.splitlines():
        try:
            msg = json.loads(line)
        except json.JSONDecodeError:
            continue
        if msg.get("reason") != "compiler-artifact" or not msg.get("executable"):
            continue
        if not msg.get("profile", {}).get("test"):
            continue
        target = msg["target"]
        kind = target["kind"][0]
        name = target["name"] if kind == "test" else f"{kind}:{target['name']}"
        binaries.append((name, msg["executable"]))
    return binaries


def list_tests(executable):
    """The test names of one binary (ignored ones included)."""
    proc = subprocess.run(
        [executable, "--list", "--format", "terse"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    if proc.returncode != 0:
        sys.exit(f"error: {executable} --list failed:\n{proc.stderr}")
    return [line[: -len(": test")] for line in proc.stdout.splitlines() if line.endswith(": test")]


def cache_summary():
    """What the disk cache's computed.log says: entries computed, and how
    many of them more than once (two tests that did the same work)."""
    try:
        lines = (CACHE / "computed.log").read_text().splitlines()
    except OSError:
        return "disk cache: nothing computed"
    by_kind = {}
    for line in lines:
        parts = line.split()
        if len(parts) == 3:
            by_kind.setdefault(parts[0], []).append(parts[1])
    text = []
    for kind, keys in sorted(by_kind.items()):
        text.append(f"{kind}: {len(keys)} computed, {len(keys) - len(set(keys))} of them again")
    return "disk cache: " + "; ".join(text)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2, help="tests at a time (default 2)")
    parser.add_argument(
        "--write-durations", action="store_true",
        help=f"write each test's time to {DURATIONS.relative_to(ROOT)} (the order of later runs)",
    )
    parser.add_argument("cargo_args", nargs="*", help="after --: arguments for cargo test (--release, --features ...)")
    args = parser.parse_args()

    known = json.loads(DURATIONS.read_text()) if DURATIONS.exists() else {}
    jobs = []
    for binary, executable in test_binaries(args.cargo_args):
        for test in list_tests(executable):
            jobs.append((known.get(f"{binary}::{test}", 0.0), binary, executable, test))
    # Longest first; unknown tests (0 s) after every known one, in name order.
    jobs.sort(key=lambda j: (-j[0], j[1], j[3]))

    shutil.rmtree(CACHE, ignore_errors=True)
    CACHE.mkdir(parents=True)
    env = dict(os.environ, SPSLAM_TEST_CACHE=str(CACHE), RUST_TEST_THREADS="1")
    lock = threading.Lock()
    results = {}
    started = time.monotonic()

    def run(job):
        _, binary, executable, test = job
        t0 = time.monotonic()
        proc = subprocess.run(
            [executable, "--exact", test, "--nocapture"],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, errors="replace",
        )
        seconds = time.monotonic() - t0
        # `--exact` with a name that runs nothing (an ignored test) passes.
        ok = proc.returncode == 0
        with lock:
            results[f"{binary}::{test}"] = (ok, seconds)
            stamp = time.monotonic() - started
            print(f"[tests {stamp:7.1f} s] {'ok  ' if ok else 'FAIL'} {seconds:7.1f} s  {binary}::{test}", flush=True)
            if not ok:
                print(proc.stdout, flush=True)
            elif seconds >= 30.0:
                # What the long tests measured (their eprintln! lines), kept in the log.
                lines = [l for l in proc.stdout.splitlines() if l and not l.startswith(("running ", "test ", "test result"))]
                for line in lines[-20:]:
                    print(f"    {line}", flush=True)

    print(f"[tests] {len(jobs)} tests from {len({j[1] for j in jobs})} binaries, {args.jobs} at a time", flush=True)
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        list(pool.map(run, jobs))

    doc = subprocess.run(["cargo", "test", "--doc", *args.cargo_args], cwd=ROOT)
    failed = sorted(name for name, (ok, _) in results.items() if not ok)
    wall = time.monotonic() - started
    slowest = sorted(results.items(), key=lambda kv: -kv[1][1])[:15]
    print(f"[tests] the slowest of {len(results)}:")
    for name, (_, seconds) in slowest:
        print(f"    {seconds:7.1f} s  {name}")
    print(f"[tests] {cache_summary()}")
    print(f"[tests] {len(results) - len(failed)} passed, {len(failed)} failed, doc-tests {'ok' if doc.returncode == 0 else 'FAILED'}; {wall:.0f} s wall")
    if args.write_durations:
        DURATIONS.write_text(
            json.dumps({name: round(s, 1) for name, (_, s) in sorted(results.items())}, indent=1) + "\n"
        )
        print(f"[tests] durations written to {DURATIONS.relative_to(ROOT)}")
    if failed or doc.returncode != 0:
        for name in failed:
            print(f"FAILED: {name}")
        sys.exit(1)


if __name__ == "__main__":
    main()
