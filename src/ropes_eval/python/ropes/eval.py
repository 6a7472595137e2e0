"""The evaluation (ropes_eval) from Python: the paper's measures on numpy arrays (MCC per
joint and by best assignment, the linear calibrations), a run's evaluation by the paper's
protocol, the suites with their report, and the whole main job (what ropes-run runs).

    >>> ropes.eval.mcc(latents, angles)                  # |Pearson| of latent k and joint k
    >>> ev = ropes.eval.evaluate_run("run", "test-data", repeats=3)
    >>> print(ev.table); ev.mcc                          # {joint: mean MCC of ROPES}
    >>> job = ropes.eval.run_main_job("1c-tiny", "out", threads=2, log=print)
"""
import dataclasses
import os

import numpy as np

from . import _eval
from .errors import ShapeError, check_callback


def _real(x, what):
    a = np.asarray(x)
    if a.dtype.kind not in "fiu":
        raise ShapeError(f"{what}: expected real numbers (a float64 array), got a {a.dtype} "
                         f"array of shape {list(a.shape)}")
    return np.ascontiguousarray(a, dtype=np.float64)


def mcc(latents, angles, kind="pearson"):
    """Per joint, |correlation| of latent column k and joint column k (latents and angles
    [n, k], n >= 2): the paper's MCC is its mean. kind "pearson" (the paper's) or "spearman".
    ValueError names the column when one is constant or not finite."""
    return _eval.per_joint_correlation(_real(latents, "latents"), _real(angles, "angles"), kind)


def correlation_matrix(latents, angles, kind="pearson"):
    """[k, d]: |correlation| of joint j (angles [n, k]) and latent l (latents [n, d])."""
    return _eval.correlation_matrix(_real(latents, "latents"), _real(angles, "angles"), kind)


@dataclasses.dataclass
class Assignment:
    """Joints matched to distinct latents with the largest total |correlation|."""
    latent_of_joint: list
    correlation: np.ndarray
    mean: float  # the best-assignment MCC of the CRL literature


def best_assignment(latents, angles, kind="pearson"):
    """The best-assignment MCC (the Hungarian algorithm on correlation_matrix; exact)."""
    d = _eval.best_assignment(_real(latents, "latents"), _real(angles, "angles"), kind)
    return Assignment(d["latent_of_joint"], d["correlation"], d["mean"])


def fit_affine(latent, joint):
    """Least squares joint ~ scale * latent + offset: (scale, offset)."""
    return _eval.fit_affine(_real(latent, "latent"), _real(joint, "joint"))


def affine_mse(scale, offset, latent, joint):
    """Mean squared error of joint ~ scale * latent + offset (rad^2 for radians)."""
    return _eval.affine_mse(scale, offset, _real(latent, "latent"), _real(joint, "joint"))


def fit_linear(latents, joint):
    """Least squares joint ~ latents @ weights + offset (minimum-norm for a dead latent):
    (weights, offset)."""
    return _eval.fit_linear(_real(latents, "latents"), _real(joint, "joint"))


def linear_mse(weights, offset, latents, joint):
    return _eval.linear_mse(_real(weights, "weights"), offset, _real(latents, "latents"),
                            _real(joint, "joint"))


@dataclasses.dataclass
class Evaluation:
    """One run on one test set (ropes_eval/run_evaluation.hpp): `results` is what
    results.json holds (methods, per joint and repeat; the protocol; the diagnostics),
    `table` the per-joint table beside the paper's numbers, `markdown` results.md,
    `calibration` calibration.json (repeat 0's affine fit, for the Estimator), `files` the
    paths written (None when nothing was)."""
    results: dict
    table: str
    markdown: str
    calibration: dict
    files: dict

    @property
    def joints(self):
        return self.results["joints"]

    def method(self, name="ropes"):
        """One method's measures, the mean over the repeats: {"mcc": [...], "mse": [...],
        "spearman", "best_assignment_mcc", "mse_all_latents", each with its "<measure>_std"},
        one value per joint (None where a latent was constant); "repeats" holds each repeat's.
        KeyError naming the methods for an unknown one."""
        methods = self.results["methods"]
        if name not in methods:
            raise KeyError(f"no method '{name}'; the evaluation has {', '.join(methods)}")
        return methods[name]

    @property
    def mcc(self):
        """{joint: ROPES' mean MCC}"""
        return dict(zip(self.joints, self.method()["mcc"]))

    @property
    def mse(self):
        """{joint: ROPES' mean MSE of the affine calibration, rad^2}"""
        return dict(zip(self.joints, self.method()["mse"]))


def evaluate_run(run, data, repeats=15, calibration_samples=1000, test_samples=500, seed=0,
                 probe_steps=3000, occlusion=0, occlusion_seed=0, threads=1, write=True,
                 out=None):
    """Evaluates the run in `run` on the dataset in `data` by the paper's protocol, as
    ropes-eval --run RUN --data DATA does, to the same numbers. With `write` it writes what
    ropes-eval writes: results.json, results.md and calibration.json, at `out` (the results
    file) or beside the run (RUN-eval/results.json), never inside it. ValueError, before
    anything is computed, for a count out of range, the run's own training set, too few
    observational samples or an `out` inside the run."""
    protocol = dict(repeats=repeats, calibration_samples=calibration_samples,
                    test_samples=test_samples, seed=seed, probe_steps=probe_steps,
                    occlusion=occlusion, occlusion_seed=occlusion_seed)
    d = _eval.evaluate_run(os.fspath(run), os.fspath(data), write,
                           None if out is None else os.fspath(out), protocol, threads)
    return Evaluation(**d)


@dataclasses.dataclass
class Report:
    """The suites' evaluation of a run (ropes_eval/suites.hpp): `report` is results.json,
    `table` the summary, `report_dir` holds results.json, results.md, report.html and (with
    the id suite) calibration.json. `stopped`: the log callback returned False."""
    report: dict
    table: str
    report_dir: str
    stopped: bool = False

    @property
    def html(self):
        return os.path.join(self.report_dir, "report.html")


def run_suites(run, suites=("id",), data=None, out=None, cache=None, dataset_config=None,
               test_seed=None,
               occlusion_sizes=(16, 32, 64), supervised=(0.01, 0.05, 0.10, 1.0),
               supervised_max_steps=0, threads=1, repeats=15, calibration_samples=1000,
               test_samples=500, seed=0, probe_steps=3000, log=None):
    """Evaluates the run on the suites (id, ood, causal, occlusion) as ropes-eval --suite
    does: each suite's test set generated into `cache` (default: $ROPES_DATA_CACHE, else the
    XDG cache) or found there, the supervised baselines, and the report in `out` (default
    RUN-eval/report). `dataset_config`: the training set's dataset config file when it is not
    installed (a robot of your own). `log(line)` gets the progress lines; returning False
    stops (the generated test sets are kept)."""
    options = dict(suites=list(suites), data=data, out=out, cache=cache,
                   dataset_config=dataset_config, test_seed=test_seed,
                   occlusion_sizes=list(occlusion_sizes), supervised=list(supervised),
                   supervised_max_steps=supervised_max_steps, threads=threads,
                   protocol=dict(repeats=repeats, calibration_samples=calibration_samples,
                                 test_samples=test_samples, seed=seed,
                                 probe_steps=probe_steps))
    check_callback(log, "log")
    d = _eval.run_suites(os.fspath(run), options, log)
    if d["stopped"]:
        return Report({}, "", "", True)
    return Report(d["report"], d["table"], d["report_dir"])


@dataclasses.dataclass
class MainJob:
    """What ropes-run made in its directory `dir`: train_data, run_dir, report_dir and the
    per-joint `table`; `evaluated` is false when the evaluation had been done before with the
    same arguments. `stopped`: the log callback returned False (call again to resume)."""
    dir: str = ""
    train_data: str = ""
    run_dir: str = ""
    report_dir: str = ""
    table: str = ""
    evaluated: bool = False
    stopped: bool = False


def run_main_job(config, out=None, seed=0, data_seed=0, dataset_config=None, threads=1,
                 suites=("id", "ood", "occlusion"), repeats=15, calibration_samples=1000,
                 test_samples=500, probe_steps=3000, supervised_max_steps=0, log=None):
    """The ROPES main job on an experiment config, as ropes-run runs it (the same bytes):
    generate the training set, train, evaluate the suites, report, into `out` (default
    runs/<config name>); resumes where an earlier call stopped. `log(stage, line)` gets the
    progress lines (stage 1 generate, 2 train, 3 evaluate); returning False stops the job at
    its next line, and Ctrl-C at its next line or training record (seen on the main thread
    only: the side-by-side AE2s of stage 3 run on threads of their own)."""
    options = dict(config=os.fspath(config), out=None if out is None else os.fspath(out),
                   seed=seed, data_seed=data_seed, dataset_config=dataset_config,
                   threads=threads, suites=list(suites), supervised_max_steps=supervised_max_steps,
                   protocol=dict(repeats=repeats, calibration_samples=calibration_samples,
                                 test_samples=test_samples, probe_steps=probe_steps))
    check_callback(log, "log")
    return MainJob(**_eval.run_main_job(options, log))
