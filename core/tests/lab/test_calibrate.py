"""`python -m bsplab calibrate`: the fit of the SAH costs (synthetic rows with
known costs, so nothing here depends on this machine's speed), its spread,
and the measured costs file that `build(..., costs="measured")` reads."""

from __future__ import annotations

import re
import tomllib

import numpy as np
import pytest

import bsplab
from bsplab import costs, scenes
from bsplab.__main__ import main as bsplab_main
from bsplab.lab import benchmarks
from bsplab.lab.benchmarks import fit_costs, spec_path
from bsplab.lab.report import calibration_lines

# The machine of the synthetic rows: ns per kd step, general step and test,
# and a per-ray base the pairing must take out.
K_KD, K_GEN, K_I, BASE = 2.0, 5.0, 20.0, 100.0


def _times(per_ray: float, rays: int, drift: np.ndarray) -> str:
    return " ".join(str(per_ray * 1e-9 * rays * d) for d in drift)


def synthetic_rows(rng, noise: float = 0.0, trees: int = 8, rounds: int = 5) -> list[dict]:
    """Per scene x workload, the kd-tree and `trees` other trees whose times
    follow the costs above; every round runs at its own speed (`drift`, the
    same for a tree and its kd pair) and each time has `noise` (relative).
    `rounds` is odd."""
    rows = []
    for scene, workload in (("a", "primary"), ("a", "random"), ("b", "random")):
        kd_counts = rng.uniform(10, 30), rng.uniform(2, 8)

        def row(method, variant, kd_steps, gen, tests):
            # The rounds' speeds, shuffled per row; their median is 1 so
            # that the kd-tree's median time is its true time.
            drift = rng.permutation(np.geomspace(0.5, 2.0, rounds))
            jitter = 1 + noise * rng.standard_normal((2, rounds))
            per_ray = BASE + K_KD * kd_steps + K_GEN * gen + K_I * tests
            kd_per_ray = BASE + K_KD * kd_counts[0] + K_I * kd_counts[1]
            return {"scene": scene, "workload": workload, "method": method,
                    "variant": variant, "rays": "1000", "steps": str(kd_steps + gen),
                    "general_steps": str(gen), "tests": str(tests),
                    "trace_s": _times(per_ray, 1000, drift * jitter[0]),
                    "kd_s": _times(kd_per_ray, 1000, drift * jitter[1])}

        rows.append(row("kd", "", *kd_counts[:1], 0.0, kd_counts[1]))
        rows[-1]["trace_s"] = rows[-1]["kd_s"]  # the kd-tree is its own pair
        for i in range(trees):
            gen = rng.uniform(0, 10) if i % 2 else 0.0
            rows.append(row("bsp" if gen else "kd", f"variant {i}", rng.uniform(5, 40), gen,
                            rng.uniform(1, 20)))
    return rows


def test_the_fit_recovers_known_costs_without_noise():
    fit = fit_costs(synthetic_rows(np.random.default_rng(3)))
    # The drift cancels in the pairing and the base in the difference.
    assert fit["ns_kd_step"] == pytest.approx(K_KD)
    assert fit["ns_general_step"] == pytest.approx(K_GEN)
    assert fit["ns_test"] == pytest.approx(K_I)
    assert fit["intersect_per_kd"] == pytest.approx(K_I / K_KD)
    assert fit["general_per_kd"] == pytest.approx(K_GEN / K_KD)
    assert fit["ns_per_ray"] == pytest.approx(BASE)
    assert fit["r2"] == pytest.approx(1.0)
    # Without noise every resample gives the same fit: no spread, stable.
    for key, (lo, hi) in fit["spread"].items():
        assert lo == pytest.approx(fit[key]) and hi == pytest.approx(fit[key])
    assert fit["stable"] is True
    assert fit["samples"] == 3 * 8 and fit["rounds"] == 5
    # Each workload alone (with its kd-trees) gives the same machine.
    assert set(fit["by_workload"]) == {"primary", "random"}
    assert fit["by_workload"]["primary"]["samples"] == 8
    for part in fit["by_workload"].values():
        assert part["intersect_per_kd"] == pytest.approx(K_I / K_KD)
        assert part["general_per_kd"] == pytest.approx(K_GEN / K_KD)


def test_the_fit_recovers_known_costs_through_noise_and_reports_its_spread():
    fit = fit_costs(synthetic_rows(np.random.default_rng(5), noise=0.01, trees=12, rounds=9))
    assert fit["intersect_per_kd"] == pytest.approx(K_I / K_KD, rel=0.1)
    assert fit["general_per_kd"] == pytest.approx(K_GEN / K_KD, rel=0.1)
    for key, (lo, hi) in fit["spread"].items():
        assert lo < hi, key                    # the noise shows
        assert lo <= fit[key] * 1.05 and fit[key] * 0.95 <= hi, key
    noisy = fit_costs(synthetic_rows(np.random.default_rng(5), noise=0.3, rounds=3))
    assert noisy["stable"] is False
    lo, hi = noisy["spread"]["intersect_per_kd"]
    assert hi - lo > fit["spread"]["intersect_per_kd"][1] - fit["spread"]["intersect_per_kd"][0]


def test_the_fit_names_what_it_lacks():
    rows = synthetic_rows(np.random.default_rng(1))
    with pytest.raises(ValueError, match="no kd row without a variant for \\[\\('a', 'primary'\\)"):
        fit_costs([r for r in rows if not (r["scene"], r["workload"], r["variant"])
                   == ("a", "primary", "")])
    few = [r for r in rows if r["scene"] == "a" and r["workload"] == "primary"][:3]
    with pytest.raises(ValueError, match="at least 3 trees that differ"):
        fit_costs(few)


def test_calibration_lines_print_each_cost_with_its_spread():
    fit = fit_costs(synthetic_rows(np.random.default_rng(2), noise=0.02))
    lines = calibration_lines(fit)
    line = next(x for x in lines if x.split()[0] == "intersect_per_kd")
    lo, hi = fit["spread"]["intersect_per_kd"]
    assert f"{fit['intersect_per_kd']:.3f}" in line and f"{lo:.3f} .. {hi:.3f}" in line
    assert any(re.fullmatch(r"\s+stable\s+(yes|no)", x) for x in lines)
    primary = fit["by_workload"]["primary"]
    assert f"  primary: intersect_per_kd {primary['intersect_per_kd']:.3f} (IQR " in lines[-2]
    assert not any("spread" in x for x in lines)


@pytest.fixture
def costs_file(tmp_path, monkeypatch):
    path = tmp_path / "machine" / "costs.toml"
    monkeypatch.setenv("BSPLAB_COSTS", str(path))
    return path


FIT = {"intersect_per_kd": 2.75, "general_per_kd": 1.25, "r2": 0.9, "samples": 20}


def test_written_costs_drive_measured_builds_as_the_explicit_options_would(costs_file):
    assert costs.costs_path() == costs_file
    assert costs.write_costs(FIT) == costs_file
    assert costs.read_costs() == {"traversal_cost": 1.0, "intersect_cost": 2.75,
                                  "general_cost": 1.25}
    # room (2k triangles): the costs still change its kd tree, and its BSP
    # builds take milliseconds (spheres' took minutes under the sanitizers).
    tris = scenes.generate("room")
    kd = bsplab.build(tris, "kd", costs="measured")
    assert kd.node_bytes() == bsplab.build(tris, "kd", traversal_cost=1.0,
                                           intersect_cost=2.75).node_bytes()
    assert kd.node_bytes() != bsplab.build(tris, "kd").node_bytes()
    bsp = bsplab.build(tris, "bsp_wn+kd", k=4, costs="measured")
    assert bsp.node_bytes() == bsplab.build(tris, "bsp_wn+kd", k=4, traversal_cost=1.0,
                                            intersect_cost=2.75,
                                            general_cost=1.25).node_bytes()
    # Without ^Kd every node of a BSP tree is a general one.
    plain = bsplab.build(tris, "bsp_wn+", k=4, costs="measured")
    assert plain.node_bytes() == bsplab.build(tris, "bsp_wn+", k=4, traversal_cost=1.25,
                                              intersect_cost=2.75).node_bytes()
    # "default" and None leave the options' defaults alone.
    assert bsplab.build(tris, "kd", costs="default").node_bytes() == \
        bsplab.build(tris, "kd").node_bytes()


def test_the_costs_file_lives_in_the_user_config_without_the_variable(monkeypatch, tmp_path):
    monkeypatch.delenv("BSPLAB_COSTS", raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert costs.costs_path() == tmp_path / "bsplab" / "costs.toml"
    monkeypatch.delenv("XDG_CONFIG_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert costs.costs_path() == tmp_path / "home" / ".config" / "bsplab" / "costs.toml"


def test_measured_costs_that_are_missing_or_broken_are_named(costs_file):
    tris = scenes.generate("room")
    with pytest.raises(ValueError, match="no measured costs: .*costs.toml does not exist.*"
                                         "calibrate --write"):
        bsplab.build(tris, "kd", costs="measured")
    costs_file.parent.mkdir(parents=True)
    costs_file.write_text("[costs\ntraversal_cost = 1\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        bsplab.build(tris, "kd", costs="measured")
    costs_file.write_text("[costs]\ntraversal_cost = 1.0\nintersect_cost = 2.0\n")
    with pytest.raises(ValueError, match="exactly traversal_cost, intersect_cost, general_cost"):
        bsplab.build(tris, "kd", costs="measured")
    costs_file.write_text("[costs]\ntraversal_cost = 1.0\nintersect_cost = -2.0\n"
                          "general_cost = 2.0\n")
    with pytest.raises(ValueError, match="intersect_cost = -2.0; a cost must be a positive"):
        bsplab.build(tris, "kd", costs="measured")


def test_measured_costs_refuse_ambiguous_or_unknown_requests(costs_file):
    costs.write_costs(FIT)
    tris = scenes.generate("room")
    with pytest.raises(ValueError, match="either costs='measured' or the costs themselves"):
        bsplab.build(tris, "kd", costs="measured", intersect_cost=3.0)
    with pytest.raises(ValueError, match="costs must be None, 'default' or 'measured'"):
        bsplab.build(tris, "kd", costs="fitted")
    # A fit that priced a test below zero is never stored.
    with pytest.raises(ValueError, match="the fit gives intersect_cost = -1.0"):
        costs.write_costs({**FIT, "intersect_per_kd": -1.0})
    assert costs.read_costs()["intersect_cost"] == 2.75


def test_the_calibrate_command_prints_the_fit_and_writes_it(tmp_path, monkeypatch, capsys):
    """The command run in this process, so that the test holds the exact fit
    it computed: the file must hold that fit's costs to the last bit and the
    printout that fit's lines. (Read back from the printout, a cost is only
    known to three digits, and whether it was positive is not known at all
    when it prints as 0.000.)"""
    path = tmp_path / "costs.toml"
    monkeypatch.setenv("BSPLAB_COSTS", str(path))
    monkeypatch.chdir(tmp_path)
    fits = []

    def calibrate(*args, **kwargs):
        fits.append(real_calibrate(*args, **kwargs))
        return fits[-1]

    real_calibrate = benchmarks.calibrate
    monkeypatch.setattr(benchmarks, "calibrate", calibrate)
    status = bsplab_main(["calibrate", "--scenes", "room", "--repeats", "2", "--write"])
    out, err = capsys.readouterr()
    assert len(fits) == 1, fits
    fit = fits[0]
    assert out.startswith("\n".join(calibration_lines(fit)) + "\n"), out
    assert set(fit) >= {"ns_kd_step", "ns_test", "intersect_per_kd", "general_per_kd",
                        "ns_per_ray", "stable", "r2", "samples", "rounds"}
    assert re.search(r"intersect_per_kd\s+\S+\s+\(IQR \S+ \.\. \S+\)", out)
    spec = tomllib.loads(spec_path("calibrate").read_text())
    trees = len(spec["method_variants"]["kd"]) - 1 + len(spec["methods"]) - 1
    assert fit["samples"] == 2 * trees  # the trees besides the kd-tree x 2 workloads
    assert (tmp_path / "out" / "bench" / "calibrate.csv").exists()
    # On a loaded machine two rounds may price a cost at zero or below: then
    # the command says so and writes nothing.
    if fit["intersect_per_kd"] > 0 and fit["general_per_kd"] > 0:
        assert status == 0, err
        assert f"written {path}" in out
        assert costs.read_costs(path) == costs.costs_from_fit(fit)
    else:
        assert status == 1 and "not written" in err
        assert not path.exists()
