"""The learner (ropes_crl) from Python: experiment configs, training a run (AE1, the LDRs,
AE2 with the score-sparsity loss) with a progress callback, and the Estimator that turns
images into latents and, with a calibration, joint angles.

    >>> config = ropes.crl.ExperimentConfig.load("1c-tiny")      # installed, or a file
    >>> ropes.crl.train(config, "data", "run", seed=0, threads=2,
    ...                 progress=lambda record: print(record["stage"], record.get("step")))
    >>> est = ropes.crl.Estimator("run")                 # uses the run's latest calibration
    >>> latents, angles = est.estimate(images)           # uint8 [n, cameras, S, S]
"""
import collections
import os

from . import _crl
from .errors import check_callback

ExperimentConfig = _crl.ExperimentConfig
ExperimentConfig.__doc__ = """An experiment config (ropes_crl/experiment_config.hpp): the
dataset it expects, the three networks and how each stage trains.
ExperimentConfig.load(name_or_path) reads a file or an installed config by name ("1c-small");
ropes.ConfigError names the file, the field, the value and what was expected."""

TrainResult = collections.namedtuple("TrainResult", ["run", "complete", "stopped"])


def _experiment(config):
    if isinstance(config, ExperimentConfig):
        return config
    return ExperimentConfig.load(config)


def train(config, data, out, seed=0, threads=1, last_stage=3, progress=None):
    """Trains (or resumes) the run of `config` (an ExperimentConfig, a file or an installed
    name) on the dataset in `data` into `out`: the bytes ropes-train writes for the same
    config, dataset, seed and threads. `last_stage` 1 stops after AE1 (and the codes), 2 after
    the LDRs, 3 runs the whole method.

    `progress(record)` gets every record written to the run's metrics.jsonl, as a dict (stage,
    step, losses, ...), from the training threads one call at a time. Returning False stops
    the training cleanly at that point (TrainResult.stopped; the run keeps its last checkpoint
    and the same call resumes it); what it raises stops it as well and is raised here, and so
    does Ctrl-C, which Python sees on the main thread only: in stage 3 the AE2s report from
    threads of their own, so Ctrl-C takes effect when the stage ends. The GIL is released while
    the run computes."""
    check_callback(progress, "progress")
    r = _crl.train(_experiment(config), os.fspath(data), os.fspath(out), seed, threads,
                   last_stage, progress)
    return TrainResult(os.fspath(out), r["complete"], r["stopped"])


def run_info(run):
    """What run.json records of a run: dir, config, joints, data_dir, dataset_id, provenance."""
    return _crl.run_info(run)


def latest_calibration(run):
    """The newest calibration.json that an evaluation of `run` wrote and that records this
    run (ropes-eval writes one beside the run); None when there is none."""
    return _crl.latest_calibration(run)


def set_num_threads(threads):
    """Threads of the Estimator's computations in this process (ropes_nn's kernels)."""
    _crl.set_num_threads(threads)


class Estimator:
    """A trained run: images -> latents -> joint angles. The latents identify each joint up
    to a monotonic map; angles need a calibration fitted on a few labelled samples, which
    ropes-eval (or ropes.eval.evaluate_run) writes as calibration.json.

    `calibration`: "latest" (the default: the run's newest evaluation's calibration when there
    is one, else none), None (latents only), or the path of a calibration.json, which must
    have been fitted for this run (ValueError naming both otherwise).
    ropes.FileFormatError names the file when the run is incomplete or a weight file does
    not match its architecture."""

    def __init__(self, run, calibration="latest"):
        self.run = os.fspath(run)
        self._est = _crl.Estimator.load(self.run)
        self.calibration = None
        if calibration == "latest":
            calibration = latest_calibration(self.run)
        if calibration is not None:
            self._est.use_calibration(self.run, calibration)
            self.calibration = os.fspath(calibration)

    @property
    def joints(self):
        """The run's joints, in latent order."""
        return self._est.joints

    @property
    def image_shape(self):
        """(cameras, S, S): one sample's images."""
        return (self._est.cameras, self._est.image_size, self._est.image_size)

    def estimate(self, images, batch=256):
        """images uint8 [n, cameras, S, S] (a dataset's `images` rows) -> (latents float32
        [n, J], angles float32 [n, J], or None without a calibration), computed `batch`
        samples at a time with the GIL released. ropes.ShapeError names the expected dtype
        and shape for anything else."""
        return self._est.estimate(images, batch)

    def __repr__(self):
        return f"Estimator({self.run!r}, joints={self.joints}, calibration={self.calibration!r})"
