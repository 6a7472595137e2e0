"""ropes.crl: the learner from Python (ropes._crl), on a synthetic two-joint dataset written
with ropes.dataset (ropes_crl does not link the simulator). Witnesses: ropes-train's bytes
for the same config, data, seed and threads; a calibration applied by numpy."""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import ropes
from ropes import crl, dataset

TRAIN = os.environ.get("ROPES_TRAIN_EXE") or shutil.which("ropes-train")
WEIGHTS = ["ae1.safetensors", "codes.npy", "ldr.a.safetensors", "ldr.b.safetensors",
           "ae2.a.safetensors", "ae2.b.safetensors", "ae2.lambda0.safetensors"]


def _bars(q, size):
    """Joint j's bar in its half of the image, at angle q[j] (as ropes_crl's C++ tests)."""
    img = np.full((size, size), 20, np.uint8)
    y, x = np.mgrid[0:size, 0:size]
    for j in range(2):
        inside = (x < size // 2) if j == 0 else (x >= size // 2)
        u = (x % (size // 2)) - (size // 2 - 1) / 2.0
        v = y - (size - 1) / 2.0
        along = u * np.cos(q[j]) + v * np.sin(q[j])
        across = -u * np.sin(q[j]) + v * np.cos(q[j])
        bar = inside & (np.abs(across) < max(1.0, 3.0 * size / 128)) & \
            (np.abs(along) < 28.0 * size / 128)
        img[bar] = 230
    return img


def write_two_bar_dataset(path, size=32, anchors=40):
    """Observational, do(a)=1, do(a)=2, do(b)=1, do(b)=2 per anchor, as ropes-generate lays
    out a dataset: images, angles, regime, anchor and the regimes in the metadata."""
    rng = np.random.default_rng(9)
    regimes = 5
    n = anchors * regimes
    images = np.zeros((n, 1, size, size), np.uint8)
    angles = np.zeros((n, 2), np.float32)
    for i in range(n):
        r = i % regimes
        for j in range(2):
            intervened = r != 0 and (r - 1) // 2 == j
            mean = 0.0 if not intervened else (-0.6 if r % 2 == 1 else 0.6)
            sd = 0.4 if intervened else 0.8
            angles[i, j] = np.clip(rng.normal(mean, sd), -1.4, 1.4)
        images[i, 0] = _bars(angles[i], size)
    regime_list = [{"name": "observational", "joint": None, "joint_index": None,
                    "intervention": None}]
    interventions = {}
    for j, name in enumerate("ab"):
        for k in (1, 2):
            regime_list.append({"name": f"do({name})={k}", "joint": name, "joint_index": j,
                                "intervention": k})
        interventions[name] = [{"mean": -0.6, "std": 0.4, "lower": -1.4, "upper": 1.4},
                               {"mean": 0.6, "std": 0.4, "lower": -1.4, "upper": 1.4}]
    metadata = {"cameras": ["cam0"], "joint_names": ["a", "b"], "regimes": regime_list,
                "distribution": {"interventions": interventions}}
    return dataset.write(path, {"images": images, "angles": angles,
                                "regime": (np.arange(n) % regimes).astype(np.int32),
                                "anchor": (np.arange(n) // regimes).astype(np.int64)},
                         metadata=metadata)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("crl")
    write_two_bar_dataset(d / "data")
    raw = crl.ExperimentConfig.load("1c-tiny").to_dict()
    raw["dataset"]["joints"] = ["a", "b"]
    raw["ae1"]["steps"] = 20
    raw["ae2"]["steps"] = 20
    raw["ldr"]["max_epochs"] = 3
    raw["log_every"] = 1
    raw["checkpoint_every"] = 5
    (d / "config.json").write_text(json.dumps(raw))
    return d


def test_a_python_run_is_ropes_trains_bytes(setup):
    records = []
    r = crl.train(setup / "config.json", setup / "data", setup / "py", seed=3, threads=2,
                  progress=records.append)
    assert r.complete and not r.stopped
    assert {rec["stage"] for rec in records} >= {"ae1", "ae2"}
    subprocess.run([TRAIN, "--config", str(setup / "config.json"), "--data",
                    str(setup / "data"), "--out", str(setup / "cpp"), "--seed", "3",
                    "--threads", "2"], check=True, capture_output=True)
    for f in WEIGHTS:
        assert (setup / "py" / f).read_bytes() == (setup / "cpp" / f).read_bytes(), f
    info = crl.run_info(setup / "py")
    assert info["joints"] == ["a", "b"] and info["config"] == "1c-tiny"


def test_a_callback_stops_training_and_the_same_call_resumes_to_the_same_bytes(setup):
    seen = []

    def stop_in_ae1(record):
        seen.append(record)
        return not (record["stage"] == "ae1" and record.get("step") == 12)

    r = crl.train(setup / "config.json", setup / "data", setup / "stopped", seed=3, threads=2,
                  progress=stop_in_ae1)
    assert r.stopped and not r.complete
    assert seen[-1]["step"] == 12
    assert not (setup / "stopped" / "ae1.safetensors").exists()
    with pytest.raises(ropes.FileFormatError, match="run.json"):
        crl.Estimator(setup / "stopped")
    r = crl.train(setup / "config.json", setup / "data", setup / "stopped", seed=3, threads=2)
    assert r.complete
    for f in WEIGHTS:
        assert (setup / "stopped" / f).read_bytes() == (setup / "py" / f).read_bytes(), f

    class Boom(Exception):
        pass

    def boom(record):
        raise Boom(record["stage"])

    with pytest.raises(Boom, match="ae1"):
        crl.train(setup / "config.json", setup / "data", setup / "boom", seed=3, progress=boom)


def test_the_estimator_takes_uint8_images_in_batches(setup):
    if not (setup / "py" / "run.json").exists():
        pytest.skip("needs the run of test_a_python_run_is_ropes_trains_bytes")
    est = crl.Estimator(setup / "py")
    assert est.joints == ["a", "b"] and est.image_shape == (1, 32, 32)
    assert est.calibration is None
    images = dataset.Dataset(setup / "data").read("images", 0, 50)
    latents, angles = est.estimate(images)
    assert latents.shape == (50, 2) and latents.dtype == np.float32 and angles is None
    small, _ = est.estimate(images, batch=7)
    np.testing.assert_allclose(small, latents, rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(est.estimate(images[:7])[0], small[:7])
    # a calibration file without a recorded run fits any run with the same joints
    cal = setup / "calibration.json"
    cal.write_text(json.dumps({"format": "ropes-calibration", "joints": ["a", "b"],
                               "scale": [2.0, -0.5], "offset": [0.25, 1.0]}))
    est = crl.Estimator(setup / "py", calibration=cal)
    latents, angles = est.estimate(images)
    np.testing.assert_allclose(angles, latents * np.array([2.0, -0.5], np.float32) +
                               np.array([0.25, 1.0], np.float32), rtol=1e-6, atol=1e-6)
    with pytest.raises(ropes.ShapeError, match=r"images: expected a uint8 array of shape "
                                               r"\[n, 1, 32, 32\], got a float32 array"):
        est.estimate(images.astype(np.float32))
    with pytest.raises(ropes.ShapeError, match=r"got a uint8 array of shape \[50, 32, 32\]"):
        est.estimate(images[:, 0])
    other = setup / "other_calibration.json"
    other.write_text(json.dumps({"format": "ropes-calibration", "joints": ["b", "a"],
                                 "scale": [1.0, 1.0], "offset": [0.0, 0.0]}))
    with pytest.raises(ValueError, match="joints"):
        crl.Estimator(setup / "py", calibration=other)


def test_bad_configs_and_datasets_are_refused_before_anything_is_written(setup, tmp_path):
    with pytest.raises(ropes.ConfigError, match="no-such-config"):
        crl.ExperimentConfig.load("no-such-config")
    raw = json.loads((setup / "config.json").read_text())
    raw["dataset"]["joints"] = ["a", "c"]
    (tmp_path / "c.json").write_text(json.dumps(raw))
    with pytest.raises(ValueError, match="'c'"):
        crl.train(tmp_path / "c.json", setup / "data", tmp_path / "run")
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())
    with pytest.raises(ropes.FileFormatError, match="nowhere"):
        crl.train(setup / "config.json", tmp_path / "nowhere", tmp_path / "run2")
