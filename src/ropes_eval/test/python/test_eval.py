"""ropes.eval: the evaluation from Python (ropes._eval), and the tiny main job from Python
against the C++ tools. Witnesses: numpy (np.corrcoef, np.polyfit, np.linalg.lstsq) and a
brute-force search over assignments for the measures; ropes-generate, ropes-train and
ropes-eval, run on the same seeds, for the pipeline (bit for bit)."""
import itertools
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import ropes
from ropes import crl, dataset, sim
from ropes import eval as reval


def _exe(name, var):
    return os.environ.get(var) or shutil.which(name)


def _correlated(n=200, k=3, d=4, seed=0):
    rng = np.random.default_rng(seed)
    angles = rng.standard_normal((n, k))
    latents = rng.standard_normal((n, d)) * 0.5
    latents[:, [2, 0, 3]] += angles * np.array([1.0, -2.0, 0.7])
    return latents, angles


def test_the_measures_match_numpy_and_a_brute_force_assignment():
    latents, angles = _correlated()
    per_joint = reval.mcc(latents[:, :3], angles)
    witness = [abs(np.corrcoef(latents[:, k], angles[:, k])[0, 1]) for k in range(3)]
    np.testing.assert_allclose(per_joint, witness, rtol=1e-12)
    m = reval.correlation_matrix(latents, angles)
    assert m.shape == (3, 4)
    np.testing.assert_allclose(m, [[abs(np.corrcoef(latents[:, l], angles[:, j])[0, 1])
                                    for l in range(4)] for j in range(3)], rtol=1e-12)
    a = reval.best_assignment(latents, angles)
    best = max(itertools.permutations(range(4), 3),
               key=lambda p: sum(m[j, p[j]] for j in range(3)))
    assert a.latent_of_joint == list(best) == [2, 0, 3]
    assert a.mean == pytest.approx(np.mean([m[j, best[j]] for j in range(3)]), rel=1e-12)
    # Spearman of distinct values: Pearson of the ranks
    ranks = lambda x: np.argsort(np.argsort(x, axis=0), axis=0).astype(float)
    np.testing.assert_allclose(reval.mcc(latents[:, :3], angles, kind="spearman"),
                               reval.mcc(ranks(latents[:, :3]), ranks(angles)), rtol=1e-12)
    scale, offset = reval.fit_affine(latents[:, 2], angles[:, 0])
    np.testing.assert_allclose([scale, offset], np.polyfit(latents[:, 2], angles[:, 0], 1),
                               rtol=1e-10)
    mse = reval.affine_mse(scale, offset, latents[:, 2], angles[:, 0])
    assert mse == pytest.approx(np.mean((scale * latents[:, 2] + offset - angles[:, 0]) ** 2))
    weights, offset = reval.fit_linear(latents, angles[:, 1])
    lstsq = np.linalg.lstsq(np.c_[latents, np.ones(len(latents))], angles[:, 1], rcond=None)[0]
    np.testing.assert_allclose(np.r_[weights, offset], lstsq, rtol=1e-9, atol=1e-12)
    assert reval.linear_mse(weights, offset, latents, angles[:, 1]) == pytest.approx(
        np.mean((latents @ weights + offset - angles[:, 1]) ** 2))


def test_bad_arrays_name_the_expected_shape():
    latents, angles = _correlated()
    with pytest.raises(ropes.ShapeError, match=r"latents: expected a float64 array of shape "
                                               r"\[n, joints\], got a float64 array of shape "
                                               r"\[200\]"):
        reval.mcc(latents[:, 0], angles)
    with pytest.raises(ValueError, match="shape"):
        reval.mcc(latents, angles)  # 4 latents for 3 joints
    with pytest.raises(ValueError, match="constant"):
        reval.mcc(np.ones((10, 1)), np.arange(10.0)[:, None])
    with pytest.raises(ropes.ShapeError, match="expected real numbers"):
        reval.mcc(np.array([["a"]]), angles)
    with pytest.raises(ValueError, match="'kendall'"):
        reval.mcc(latents[:, :3], angles, kind="kendall")


PROTOCOL = dict(repeats=3, calibration_samples=20, test_samples=20, probe_steps=100)


def test_a_tiny_python_run_equals_the_cpp_tools_bit_for_bit(tmp_path):
    py, cpp = tmp_path / "py", tmp_path / "cpp"
    # Python: generate, train, evaluate
    for seed in (0, 1):
        r = sim.generate_dataset("tiny-1c", py / f"data{seed}", seed=seed, threads=2)
        assert r.complete
    t = crl.train("1c-tiny", py / "data0", py / "run", seed=0, threads=2)
    assert t.complete
    ev = reval.evaluate_run(py / "run", py / "data1", threads=2, **PROTOCOL)
    # the same with the C++ tools
    for seed in (0, 1):
        subprocess.run([_exe("ropes-generate", "ROPES_GENERATE_EXE"), "--config", "tiny-1c",
                        "--seed", str(seed), "--out", str(cpp / f"data{seed}")], check=True,
                       capture_output=True)
    subprocess.run([_exe("ropes-train", "ROPES_TRAIN_EXE"), "--config", "1c-tiny", "--data",
                    str(cpp / "data0"), "--out", str(cpp / "run"), "--threads", "2"],
                   check=True, capture_output=True)
    subprocess.run([_exe("ropes-eval", "ROPES_EVAL_EXE"), "--run", str(cpp / "run"), "--data",
                    str(cpp / "data1"), "--threads", "2", "--repeats", "3",
                    "--calibration-samples", "20", "--test-samples", "20", "--probe-steps",
                    "100"], check=True, capture_output=True)
    for f in ("data0/manifest.json", "data1/manifest.json", "data0/shards/images-00000.npy",
              "run/ae1.safetensors", "run/codes.npy", "run/ae2.panda_joint4.safetensors",
              "run/ae2.lambda0.safetensors", "run/ldr.panda_joint6.safetensors"):
        assert (py / f).read_bytes() == (cpp / f).read_bytes(), f
    # the evaluation: every number the same, bit for bit; files where ropes-eval puts them
    cpp_results = json.loads((cpp / "run-eval" / "results.json").read_text())
    assert ev.files["results"] == str(py / "run-eval" / "results.json")
    assert json.loads((py / "run-eval" / "results.json").read_text()) == ev.results
    assert ev.results["methods"] == cpp_results["methods"]
    assert ev.results["protocol"] == cpp_results["protocol"]
    cpp_cal = json.loads((cpp / "run-eval" / "calibration.json").read_text())
    assert ev.calibration["scale"] == cpp_cal["scale"]
    assert ev.calibration["offset"] == cpp_cal["offset"]
    assert list(ev.mcc) == ["panda_joint2", "panda_joint4", "panda_joint6"]
    assert "| panda_joint6 |" in ev.table
    # the Estimator, with the calibration the evaluation wrote, on the test set's images
    est = crl.Estimator(py / "run")
    assert est.calibration == str(py / "run-eval" / "calibration.json")
    test = dataset.Dataset(py / "data1")
    obs = test.regime("observational")
    latents, angles = est.estimate(test.take("images", obs))
    assert angles.shape == (len(obs), 3)
    truth = test.take("angles", obs)[:, [1, 3, 5]]
    per_joint = reval.mcc(latents, truth)
    assert per_joint.shape == (3,) and np.all((per_joint >= 0) & (per_joint <= 1))


def test_bad_evaluations_are_refused_before_anything_is_written(tmp_path):
    sim.generate_dataset("tiny-1c", tmp_path / "data0", seed=0)
    crl.train("1c-tiny", tmp_path / "data0", tmp_path / "run", seed=0)
    with pytest.raises(ValueError, match="repeats"):
        reval.evaluate_run(tmp_path / "run", tmp_path / "data0", **dict(PROTOCOL, repeats=0))
    with pytest.raises(ValueError, match="trained on"):
        reval.evaluate_run(tmp_path / "run", tmp_path / "data0", **PROTOCOL)
    with pytest.raises(ValueError, match="inside the run directory"):
        reval.evaluate_run(tmp_path / "run", tmp_path / "data0", out=tmp_path / "run" / "x.json",
                           **PROTOCOL)
    with pytest.raises(ValueError, match="calibration.json"):
        reval.evaluate_run(tmp_path / "run", tmp_path / "data0",
                           out=tmp_path / "e" / "calibration.json", **PROTOCOL)
    assert not (tmp_path / "run-eval").exists() and not (tmp_path / "e").exists()
    with pytest.raises(ValueError, match="'odd' is not a suite"):
        reval.run_suites(tmp_path / "run", suites=["odd"])


def test_bad_arguments_name_the_field_before_anything_runs(tmp_path):
    with pytest.raises(ValueError, match=r"repeats is 3\.0; expected an int"):
        reval.evaluate_run(tmp_path / "run", tmp_path / "data", repeats=3.0)
    with pytest.raises(ValueError, match=r"seed is -1; expected an int >= 0"):
        reval.evaluate_run(tmp_path / "run", tmp_path / "data", seed=-1)
    with pytest.raises(ValueError, match=r"threads is '2'; expected an int"):
        reval.run_main_job("1c-tiny", tmp_path / "job", threads="2")
    with pytest.raises(TypeError, match=r"log is 5 \(int\); expected a callable or None"):
        reval.run_main_job("1c-tiny", tmp_path / "job", log=5)
    with pytest.raises(TypeError, match=r"progress is 'x' \(str\); expected a callable"):
        sim.generate_dataset("tiny-1c", tmp_path / "data", progress="x")
    assert not (tmp_path / "job").exists() and not (tmp_path / "data").exists()
