"""The MSE model of paper §6 (upsr.research.analysis): exact median variance vs integration and
Monte-Carlo, Cramér–Rao bound, bias, ρ fit, the `upsr analyze` command, the OpenCV plots."""

from __future__ import annotations

import csv
import math
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy import integrate

from upsr.apps.cli import main as cli
from upsr.errors import InputError
from upsr.research import analysis
from upsr.viz.figures import Series, line_plot


# -------------------------------------------------------------------------------------------------
# independent numerical integration of the order-statistic densities (Laplace, scale b = 1)
# -------------------------------------------------------------------------------------------------
def _cdf(x: float) -> float:
    return 0.5 * math.exp(x) if x < 0 else 1.0 - 0.5 * math.exp(-x)


def _pdf(x: float) -> float:
    return 0.5 * math.exp(-abs(x))


def _quad(g, lo: float, hi: float) -> float:  # type: ignore[no-untyped-def]
    return integrate.quad(g, lo, hi, epsabs=1e-14, epsrel=1e-12, limit=200)[0]


def _order_moment(n: int, i: int, power: int) -> float:
    """E[X_(i:n)^power], both half-lines integrated separately (the density has a kink at 0)."""
    c = math.factorial(n) / (math.factorial(i - 1) * math.factorial(n - i))

    def g(x: float) -> float:
        f = _cdf(x)
        return x**power * c * f ** (i - 1) * (1 - f) ** (n - i) * _pdf(x)

    return _quad(g, -np.inf, 0.0) + _quad(g, 0.0, np.inf)


def _cross_moment(n: int, m: int) -> float:
    """E[X_(m:n) X_(m+1:n)] from the joint density, over x < y in three smooth regions."""
    c = math.factorial(n) / (math.factorial(m - 1) * math.factorial(n - m - 1))

    def g(y: float, x: float) -> float:
        return x * y * c * _cdf(x) ** (m - 1) * _pdf(x) * _pdf(y) * (1 - _cdf(y)) ** (n - m - 1)

    opts = {"epsabs": 1e-13, "epsrel": 1e-11}
    both_pos = integrate.dblquad(g, 0.0, np.inf, lambda x: x, lambda x: np.inf, **opts)[0]
    both_neg = integrate.dblquad(g, -np.inf, 0.0, lambda x: x, lambda x: 0.0, **opts)[0]
    lo = _quad(lambda x: x * _cdf(x) ** (m - 1) * _pdf(x), -np.inf, 0.0)
    hi = _quad(lambda y: y * _pdf(y) * (1 - _cdf(y)) ** (n - m - 1), 0.0, np.inf)
    return both_pos + both_neg + c * lo * hi


def _median_variance_quad(n: int) -> float:
    """var(median)/σ² by numerical integration (σ² = 2 b² = 2)."""
    if n % 2:
        k = (n + 1) // 2
        var = _order_moment(n, k, 2) - _order_moment(n, k, 1) ** 2
    else:
        m = n // 2
        e2 = _order_moment(n, m, 2) + _order_moment(n, m + 1, 2) + 2 * _cross_moment(n, m)
        e1 = _order_moment(n, m, 1) + _order_moment(n, m + 1, 1)
        var = e2 / 4 - (e1 / 2) ** 2
    return var / 2.0


# -------------------------------------------------------------------------------------------------
# exact variance
# -------------------------------------------------------------------------------------------------
def test_known_small_values() -> None:
    assert [analysis.median_variance_fraction(n) for n in (1, 2, 3, 4)] == [
        Fraction(1),
        Fraction(1, 2),
        Fraction(23, 72),
        Fraction(121, 576),
    ]
    # N = 1: a single Laplace sample (variance σ²); N = 2: the mean of two (σ²/2)
    assert analysis.median_variance(1, 30.0) == pytest.approx(900.0, rel=1e-15)
    assert analysis.median_variance(2, 30.0) == pytest.approx(450.0, rel=1e-15)


@pytest.mark.parametrize("n", range(1, 13))
def test_closed_form_equals_numerical_integration(n: int) -> None:
    assert analysis.median_variance_factor(n) == pytest.approx(_median_variance_quad(n), rel=1e-8)


def test_two_closed_forms_agree_exactly() -> None:
    # Rényi/binomial positive sums vs the corrected eq. (36)/(37) alternating sums: same rational
    for n in range(1, 31):
        assert analysis.median_variance_fraction(n) == analysis._order_statistic_fraction(n), n


def test_float_factor_matches_rational() -> None:
    for n in [*range(1, 61), 101, 250]:
        exact = float(analysis.median_variance_fraction(n))
        assert analysis.median_variance_factor(n) == pytest.approx(exact, rel=1e-13), n


def test_large_n_path_and_asymptote() -> None:
    # the exact-integer path (N <= 1024) and the log-gamma path (N > 1024) are both exact
    for n in (1024, 1025, 1500):
        exact = float(analysis.median_variance_fraction(n))
        assert analysis.median_variance_factor(n) == pytest.approx(exact, rel=1e-11), n
    c = [analysis.median_variance_factor(n) for n in range(1019, 1031)]
    assert np.all(np.diff(c) < 0)
    # tends to the Cramér–Rao factor 1/(2N), excess ~ 4/sqrt(2 pi N)
    n = 100_000
    excess = analysis.median_variance_factor(n) * 2 * n - 1
    assert excess * math.sqrt(n) == pytest.approx(4 / math.sqrt(2 * math.pi), rel=0.01)


def test_bound_below_variance_for_every_n() -> None:
    sigma = np.array([1.0, 30.0, 100.0])
    for n in range(1, 301):
        var = analysis.median_variance(n, sigma)
        crb = analysis.cramer_rao_bound(n, sigma)
        assert np.all(var > crb), n
        assert np.allclose(crb, sigma**2 / (2 * n))
    # at N = 1 the median is the sample itself: σ², twice the bound (not equal to it)
    assert analysis.median_variance(1, 10.0) == pytest.approx(2 * analysis.cramer_rao_bound(1, 10))


def test_vectorised_over_sigma() -> None:
    s = np.array([[0.0, 10.0], [30.0, 100.0]])
    v = analysis.median_variance(9, s)
    assert v.shape == s.shape
    np.testing.assert_allclose(v, analysis.median_variance_factor(9) * s**2, rtol=1e-15)
    assert isinstance(analysis.median_variance(9, 30), float)
    assert analysis.median_variance(9, 0.0) == 0.0


@pytest.mark.parametrize("bad", [0, -3, 2.5, 3.0, True, "9", None])
def test_bad_n_frames(bad: object) -> None:
    with pytest.raises(InputError):
        analysis.median_variance(bad, 30.0)  # type: ignore[arg-type]
    with pytest.raises(InputError):
        analysis.cramer_rao_bound(bad, 30.0)  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf, [1.0, -2.0], "x"])
def test_bad_sigma(bad: object) -> None:
    with pytest.raises(InputError):
        analysis.median_variance(5, bad)  # type: ignore[arg-type]


def test_numpy_integer_n_accepted() -> None:
    assert analysis.median_variance(np.int64(5), 1.0) == pytest.approx(5057 / 28800)


# -------------------------------------------------------------------------------------------------
# the printed eq. (35)-(37)
# -------------------------------------------------------------------------------------------------
def test_printed_equations_are_wrong_as_documented() -> None:
    for n in range(1, 26):
        exact = analysis.median_variance_factor(n)
        swapped = analysis._printed_variance_factor(n, swap_parity=True)
        if n % 2:  # eq. (36) applied to odd N: exactly half the true variance
            assert swapped == pytest.approx(exact / 2, rel=1e-12)
        elif n == 2:  # eq. (37): one term, the wrong binomial C((N-1)/2, 0) = 1 is harmless
            assert swapped == pytest.approx(exact, rel=1e-12)
        else:  # wrong binomial C((N-1)/2, k) instead of C(N/2-1, k): 10-20 % too small
            assert 0.78 < swapped / exact < 0.9
        # as labelled (parity swapped, half-integer factorials) it is not even close
        assert abs(analysis._printed_variance_factor(n) / exact - 1) > 0.05
    # as printed the odd-N variance falls below the Cramér–Rao bound σ²/(2N)
    assert analysis._printed_variance_factor(25, swap_parity=True) < 1 / 50


# -------------------------------------------------------------------------------------------------
# Monte-Carlo
# -------------------------------------------------------------------------------------------------
def test_monte_carlo_agrees_within_3_percent() -> None:
    rng = np.random.default_rng(12345)
    for n in range(1, 16):
        mc = analysis.monte_carlo_median_variance(n, 30.0, 200_000, rng)
        exact = analysis.median_variance(n, 30.0)
        assert mc == pytest.approx(exact, rel=0.03), n


def test_monte_carlo_shapes_seed_and_zero_sigma() -> None:
    a = analysis.monte_carlo_median_variance(4, [0.0, 10.0, 20.0], 5000, 7)
    b = analysis.monte_carlo_median_variance(4, [0.0, 10.0, 20.0], 5000, 7)
    assert a.shape == (3,)
    np.testing.assert_array_equal(a, b)
    assert a[0] == 0.0
    assert np.all(a[1:] > 0)
    assert isinstance(analysis.monte_carlo_median_variance(3, 1.0, 10, 0), float)
    with pytest.raises(InputError):
        analysis.monte_carlo_median_variance(3, 1.0, 0, 0)


# -------------------------------------------------------------------------------------------------
# bias, MSE, ρ fit
# -------------------------------------------------------------------------------------------------
def test_bias_and_mse() -> None:
    assert analysis.bias_sq(1000, 1, 7.0) == 0.0  # r = 1: unbiased
    assert analysis.bias_sq(10, 4, 2.0) == pytest.approx(10 * 15 * 4.0)
    np.testing.assert_allclose(analysis.bias_sq(1, 2, [1.0, -2.0]), [3.0, 12.0])
    n, sigma, r, rho = 500, 25.0, 2, 3.0
    expected = n * analysis.median_variance(9, sigma) + n * (r * r - 1) * rho**2
    assert analysis.mse(9, sigma, r, rho, n) == pytest.approx(expected)
    assert analysis.mse(9, sigma, 1, rho) == pytest.approx(analysis.median_variance(9, sigma))
    with pytest.raises(InputError):
        analysis.bias_sq(10, 0, 1.0)
    with pytest.raises(InputError):
        analysis.bias_sq(0, 2, 1.0)
    with pytest.raises(InputError):
        analysis.bias_sq(10, 2, math.nan)


def _fused_with_bias(
    rho: float, r: int, n: int, sigma: float, shape: tuple[int, int], seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Truth, and the median of n noisy frames plus a ±ρ√(r²−1) per-pixel error."""
    rng = np.random.default_rng(seed)
    truth = rng.uniform(500.0, 4000.0, shape)
    frames = truth + rng.laplace(0.0, sigma / math.sqrt(2), (n, *shape))
    sign = rng.choice([-1.0, 1.0], shape)
    return np.median(frames, axis=0) + sign * rho * math.sqrt(r * r - 1), truth


@pytest.mark.parametrize(("rho", "r"), [(4.0, 2), (6.0, 4), (1.5, 8)])
def test_estimate_rho_recovers_planted_value(rho: float, r: int) -> None:
    n, sigma = 9, 30.0
    fused, truth = _fused_with_bias(rho, r, n, sigma, (300, 400), seed=int(rho * 10 + r))
    assert analysis.estimate_rho(fused, truth, r, n, sigma) == pytest.approx(rho, rel=0.05)


def test_estimate_rho_masks_and_edge_cases() -> None:
    n, sigma, r, rho = 5, 20.0, 2, 5.0
    fused, truth = _fused_with_bias(rho, r, n, sigma, (200, 300), seed=3)
    ref = analysis.estimate_rho(fused, truth, r, n, sigma)
    # invalid pixels (0 / NaN in either image) and masked-out outliers do not count
    f2, t2 = fused.copy(), truth.copy()
    f2[:20] = 0.0
    t2[:, :10] = np.nan
    f2[-5:] += 5000.0
    valid = np.ones(f2.shape, bool)
    valid[-5:] = False
    est = analysis.estimate_rho(f2, t2, r, n, sigma, valid=valid)
    assert est == pytest.approx(ref, rel=0.05)
    assert est == pytest.approx(rho, rel=0.05)
    # r = 1: no bias term in the model
    assert analysis.estimate_rho(fused, truth, 1, n, sigma) == 0.0
    # an error smaller than the noise variance clips to 0
    clean, truth0 = _fused_with_bias(0.0, 2, n, sigma, (50, 50), seed=4)
    assert analysis.estimate_rho(clean, truth0, 2, n, 10 * sigma) == 0.0
    with pytest.raises(InputError):
        analysis.estimate_rho(fused, truth[:-1], r, n, sigma)
    with pytest.raises(InputError):
        analysis.estimate_rho(np.zeros((4, 4)), np.ones((4, 4)), r, n, sigma)
    with pytest.raises(InputError):
        analysis.estimate_rho(fused, truth, r, n, sigma, valid=np.ones((2, 2), bool))


# -------------------------------------------------------------------------------------------------
# `upsr analyze`
# -------------------------------------------------------------------------------------------------
def _run(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    rc = cli.main(["analyze", *map(str, args)])
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_cli_analyze_writes_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "a" / "b"
    rc, stdout, err = _run(capsys, "--out", out, "--max-frames", 6, "--trials", 3000, "--seed", 1)
    assert rc == 0, err
    names = [f"analysis_vs_{w}.{e}" for w in ("n", "sigma") for e in ("csv", "png", "svg")]
    assert sorted(p.name for p in out.iterdir()) == names
    rows = _read_csv(out / "analysis_vs_n.csv")
    assert [int(r["n_frames"]) for r in rows] == list(range(1, 7))
    for r in rows:
        n = int(r["n_frames"])
        assert float(r["variance_mm2"]) == pytest.approx(analysis.median_variance(n, 30.0))
        assert float(r["crb_mm2"]) == pytest.approx(900.0 / (2 * n))
        assert float(r["mc_variance_mm2"]) == pytest.approx(float(r["variance_mm2"]), rel=0.15)
    srows = _read_csv(out / "analysis_vs_sigma.csv")
    assert [float(r["sigma_mm"]) for r in srows] == [float(s) for s in range(0, 101, 5)]
    assert {int(r["n_frames"]) for r in srows} == {9}
    for name in ("analysis_vs_n.png", "analysis_vs_sigma.png"):
        img = cv2.imread(str(out / name), cv2.IMREAD_UNCHANGED)
        assert img is not None and img.ndim == 3 and img.shape[2] == 3
    svg = (out / "analysis_vs_sigma.svg").read_text()
    assert "noise standard deviation σ [mm]" in svg and "variance of the median [mm²]" in svg
    assert "Cramér–Rao bound σ²/(2N)" in svg
    assert "CRB" in stdout and "analysis_vs_n.csv" in stdout
    assert len(stdout.splitlines()) >= 6 + 3
    # same seed → same numbers
    rc, stdout2, _ = _run(capsys, "--out", out, "--max-frames", 6, "--trials", 3000, "--seed", 1)
    assert rc == 0 and stdout2 == stdout
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary debris


@pytest.mark.parametrize(
    "args",
    [
        ["--sigma", "0"],
        ["--sigma", "-5"],
        ["--sigma", "nan"],
        ["--sigma", "1e200"],  # (overflowed into an empty plot)
        ["--max-frames", "0"],
        ["--max-frames", "1001"],
        ["--trials", "0"],
        ["--trials", "abc"],
        ["--seed", "-1"],
        ["--bogus"],
    ],
)
def test_cli_analyze_bad_parameters(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str]
) -> None:
    out = tmp_path / "res"
    rc, _stdout, err = _run(capsys, "--out", out, "--trials", 10, *args)
    assert rc == 2
    assert err.startswith("upsr: error:") and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_cli_analyze_out_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    rc, _, err = _run(capsys, "--out", f, "--max-frames", 2, "--trials", 10)
    assert rc == 2 and "not a folder" in err


# -------------------------------------------------------------------------------------------------
# plotting
# -------------------------------------------------------------------------------------------------
def test_line_plot_validates() -> None:
    x = np.arange(1, 11)
    plot = line_plot([Series(x, np.r_[0.0, 1.2 / x[1:]], "c", "red", "markers")], log_y=True)
    assert plot.log_y and np.isnan(plot.series[0][2][0])  # y <= 0 is not drawn on a log axis
    with pytest.raises(InputError):
        line_plot([])
    with pytest.raises(InputError):
        line_plot([Series([1, 2, 3], [1, 2])])
    with pytest.raises(InputError):
        line_plot([Series([1, 2], [np.nan, np.nan])])
    with pytest.raises(InputError):
        line_plot([Series([1, 2], [1, 2])], size=(100, 100))
    with pytest.raises(InputError):
        line_plot([Series([1, 2], [1, 2], style="dotted")])  # type: ignore[arg-type]
    with pytest.raises(InputError, match="log axis"):
        line_plot([Series([1, 2], [1, 2])], log_y=True, ylim=(0.0, 1.0))
    with pytest.raises(InputError, match="legend"):
        line_plot([Series([1, 2], [1, 2])], legend="middle")  # type: ignore[arg-type]
