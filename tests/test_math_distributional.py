"""HuRi's math against independent computations: energy distance, distortions, IQR, SR(lambda) targets,
the expectation loss and the RND novelty."""

import numpy as np
import pytest
import torch as th
from scipy import stats

from sb3_huri.common import (
    RandomNetworkDistillation,
    cvar_weights,
    distortion_weights,
    energy_distance,
    expectation_loss,
    interpolated_quantile,
    interquartile_range,
    iqr_risk_level,
    sr_lambda_targets,
    wang_weights,
)
from sb3_huri.common.quantiles import NUMPY_ORDER_ROWS, sorted_atoms


def pairwise_energy_distance(x: th.Tensor, y: th.Tensor) -> th.Tensor:
    """Eq. (4) written literally with all N x M pairs."""

    def mean_abs(a: th.Tensor, b: th.Tensor) -> th.Tensor:
        return (a[..., :, None] - b[..., None, :]).abs().mean(dim=(-1, -2))

    return 2 * mean_abs(x, y) - mean_abs(x, x) - mean_abs(y, y)


# --- sorting atoms ---------------------------------------------------------------------------------


@pytest.mark.parametrize("rows", [8, NUMPY_ORDER_ROWS + 3])
def test_sorted_atoms_are_torchs_sort_and_carry_each_atoms_gradient(rows):
    """Both paths (torch's sort for a few rows, numpy's order from ``NUMPY_ORDER_ROWS`` on) give torch's
    sorted values, and the gradient of a weighted sum of the sorted atoms lands on the atom each came from."""
    atoms = th.randn(rows, 64, dtype=th.float64, requires_grad=True)
    weights = th.rand(64, dtype=th.float64)
    ours = sorted_atoms(atoms)
    reference = th.sort(atoms, dim=-1).values
    assert th.equal(ours, reference)
    (ours_grad,) = th.autograd.grad((ours * weights).sum(), atoms)
    (reference_grad,) = th.autograd.grad((reference * weights).sum(), atoms)
    assert th.equal(ours_grad, reference_grad)


# --- energy distance ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("n", "m"), [(64, 64), (7, 3), (1, 5)])
def test_energy_distance_is_the_square_of_scipys(n, m):
    rng = np.random.default_rng(n * 100 + m)
    x, y = rng.normal(size=(5, n)), rng.normal(1.0, 2.0, size=(5, m))
    ours = energy_distance(th.as_tensor(x), th.as_tensor(y)).numpy()
    # scipy returns sqrt(2 E|X-Y| - E|X-X'| - E|Y-Y'|).
    reference = [stats.energy_distance(x[i], y[i]) ** 2 for i in range(5)]
    np.testing.assert_allclose(ours, reference, rtol=1e-10, atol=1e-12)


def test_energy_distance_gradients_match_the_pairwise_formula():
    x = th.randn(6, 16, dtype=th.float64, requires_grad=True)
    y = (3.0 * th.randn(6, 9, dtype=th.float64) + 1.0).requires_grad_()
    ours, reference = energy_distance(x, y), pairwise_energy_distance(x, y)
    th.testing.assert_close(ours, reference)
    for ours_grad, reference_grad in zip(
        th.autograd.grad(ours.sum(), (x, y)), th.autograd.grad(reference.sum(), (x, y)), strict=True
    ):
        th.testing.assert_close(ours_grad, reference_grad)


def test_energy_distance_is_zero_for_equal_sets_and_accurate_far_from_zero_in_float32():
    x = th.randn(4, 64)
    th.testing.assert_close(energy_distance(x, x[:, th.randperm(64)]), th.zeros(4), atol=1e-5, rtol=0)
    # Large returns: the result only depends on the differences.
    shifted = energy_distance(x + 1e4, x.flip(-1) * 1.5 + 1e4)
    th.testing.assert_close(shifted, energy_distance(x, x.flip(-1) * 1.5), atol=2e-3, rtol=1e-3)


# --- distortion weights ------------------------------------------------------------------------------


def test_wang_weights_for_beta_one_and_five_atoms():
    weights = wang_weights(th.tensor(1.0, dtype=th.float64), 5)
    np.testing.assert_allclose(weights.numpy(), [0.563, 0.209, 0.123, 0.072, 0.033], atol=1e-3)


def test_wang_weights_match_scipy_normal_and_sum_to_one():
    betas = np.array([-2.0, -0.7, 0.0, 0.3, 1.0, 1.9])
    levels = np.linspace(0, 1, 11)
    reference = np.diff(stats.norm.cdf(stats.norm.ppf(levels)[None] + betas[:, None]), axis=1)
    weights = wang_weights(th.as_tensor(betas), 10).numpy()
    np.testing.assert_allclose(weights, reference, atol=1e-12)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-12)
    assert (weights >= 0).all()


def test_wang_sign_convention_beta_positive_is_risk_averse():
    atoms = th.sort(th.randn(8, 32), dim=-1).values
    mean = atoms.mean(dim=-1)
    value = lambda beta: (wang_weights(th.full((8,), beta), 32) * atoms).sum(dim=-1)  # noqa: E731
    assert (value(1.0) < mean).all()
    assert (value(-1.0) > mean).all()
    th.testing.assert_close(value(0.0), mean)


def test_cvar_weights_by_hand():
    np.testing.assert_allclose(cvar_weights(th.tensor(0.5), 4).numpy(), [0.5, 0.5, 0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(cvar_weights(th.tensor(0.5), 5).numpy(), [0.4, 0.4, 0.2, 0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(cvar_weights(th.tensor(1.0), 4).numpy(), [0.25] * 4, atol=1e-7)
    # Batched per-state levels: each row is a convex combination.
    weights = cvar_weights(th.tensor([0.1, 0.5, 1.0]), 64)
    th.testing.assert_close(weights.sum(dim=-1), th.ones(3))


def test_distortion_weights_dispatch_and_cvar_clipping():
    risk = th.tensor([0.5, 1.7])
    th.testing.assert_close(distortion_weights("wang", risk, 8), wang_weights(risk, 8))
    # A CVaR level above 1 (e.g. raised by the RND bonus) is the risk-neutral mean.
    th.testing.assert_close(distortion_weights("cvar", risk, 8)[1], th.full((8,), 1 / 8))
    with pytest.raises(ValueError, match="wang"):
        distortion_weights("exponential", risk, 8)


# --- quantiles and IQR -------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 5, 64])
@pytest.mark.parametrize("level", [0.0, 0.1, 0.25, 0.5, 0.75, 0.99, 1.0])
def test_interpolated_quantile_is_numpys_hazen_quantile(n, level):
    atoms = np.sort(np.random.default_rng(n).normal(size=(3, n)), axis=-1)
    ours = interpolated_quantile(th.as_tensor(atoms), level).numpy()
    np.testing.assert_allclose(ours, np.quantile(atoms, level, axis=-1, method="hazen"), atol=1e-12)


def test_interquartile_range_and_risk_levels():
    atoms = np.sort(np.random.default_rng(0).normal(scale=[[0.1], [0.5], [2.0]], size=(3, 64)), axis=-1)
    iqr = interquartile_range(th.as_tensor(atoms))
    reference = np.quantile(atoms, 0.75, axis=-1, method="hazen") - np.quantile(
        atoms, 0.25, axis=-1, method="hazen"
    )
    np.testing.assert_allclose(iqr.numpy(), reference, atol=1e-12)
    levels = iqr_risk_level(th.tensor([0.1, 0.3, 0.5, 0.7, 0.9]), (0.3, 0.7), (-1.0, 0.0, 1.0))
    np.testing.assert_array_equal(levels.numpy(), [-1.0, 0.0, 0.0, 0.0, 1.0])


# --- SR(lambda) targets ------------------------------------------------------------------------------


def _chain():
    """One env, 7 steps: a terminal on step 2 (s_3 starts a new episode), a time-out on step 4."""
    rng = np.random.default_rng(3)
    n_steps, n_atoms = 7, 4
    rewards = rng.normal(size=(n_steps, 1)).astype(np.float32)
    atoms = np.sort(rng.normal(size=(n_steps, 1, n_atoms)), axis=-1).astype(np.float32)
    episode_starts = np.zeros((n_steps, 1), dtype=np.float32)
    episode_starts[[0, 3, 5]] = 1.0
    bootstrap = np.zeros_like(atoms)
    bootstrap[4] = np.sort(rng.normal(size=(1, n_atoms)), axis=-1)  # final state of the truncated episode
    last_atoms = np.sort(rng.normal(size=(1, n_atoms)), axis=-1).astype(np.float32)
    return rewards, atoms, episode_starts, bootstrap, last_atoms


def test_sr_lambda_one_is_the_discounted_return_from_the_bootstrap():
    rewards, atoms, starts, bootstrap, last_atoms = _chain()
    gamma = 0.9
    targets = sr_lambda_targets(rewards, atoms, starts, last_atoms, np.zeros(1), gamma, 1.0, bootstrap)
    # Episodes: steps 0-2 (terminal), 3-4 (time-out: bootstrap from its last state), 5-6 (bootstrap from s_7).
    expected = np.zeros_like(atoms)
    for first, last, tail in [(0, 2, 0.0 * last_atoms), (3, 4, bootstrap[4]), (5, 6, last_atoms)]:
        for step in range(first, last + 1):
            discounted = sum(gamma ** (k - step) * rewards[k, 0] for k in range(step, last + 1))
            expected[step] = discounted + gamma ** (last + 1 - step) * tail
    np.testing.assert_allclose(targets, expected, rtol=1e-5, atol=1e-5)


def test_sr_lambda_zero_is_the_one_step_target():
    rewards, atoms, starts, bootstrap, last_atoms = _chain()
    gamma = 0.9
    targets = sr_lambda_targets(rewards, atoms, starts, last_atoms, np.zeros(1), gamma, 0.0, bootstrap)
    next_atoms = {
        0: atoms[1],
        1: atoms[2],
        2: 0 * atoms[0],
        3: atoms[4],
        4: bootstrap[4],
        5: atoms[6],
        6: last_atoms,
    }
    for step, following in next_atoms.items():
        np.testing.assert_allclose(targets[step], rewards[step] + gamma * following, rtol=1e-6, atol=1e-6)


def test_sr_lambda_mixture_has_the_td_lambda_return_as_its_mean():
    """Averaged over many atoms, the SR(lambda) target is the TD(lambda) return of the atom means."""
    rng = np.random.default_rng(0)
    n_steps, n_envs, n_atoms, gamma, lam = 12, 2, 20_000, 0.95, 0.6
    rewards = rng.normal(size=(n_steps, n_envs))
    atoms = rng.normal(loc=rng.normal(size=(n_steps, n_envs, 1)), size=(n_steps, n_envs, n_atoms))
    starts = (rng.random((n_steps, n_envs)) < 0.15).astype(np.float64)
    last_atoms = rng.normal(size=(n_envs, n_atoms))
    dones = np.array([0.0, 1.0])
    targets = sr_lambda_targets(rewards, atoms, starts, last_atoms, dones, gamma, lam, rng=rng)
    # TD(lambda) returns of the means: G_t = r_t + gamma (1 - d) ((1 - lam) V_{t+1} + lam G_{t+1}).
    values, returns = atoms.mean(-1), np.zeros((n_steps, n_envs))
    next_return, next_value = last_atoms.mean(-1), last_atoms.mean(-1)
    for step in reversed(range(n_steps)):
        continues = 1.0 - (dones if step == n_steps - 1 else starts[step + 1])
        returns[step] = rewards[step] + gamma * continues * ((1 - lam) * next_value + lam * next_return)
        next_return, next_value = returns[step], values[step]
    np.testing.assert_allclose(targets.mean(-1), returns, atol=0.05)


# --- expectation loss (eq. 5) -------------------------------------------------------------------------


def test_expectation_loss_readings_match_numpy():
    rng = np.random.default_rng(0)
    atoms = np.sort(rng.normal(size=(6, 8)), axis=-1)
    targets = rng.normal(1.0, 2.0, size=(6, 5))
    beta = rng.uniform(-1, 1, size=6)
    # Wang weights from scipy's normal distribution, independently of sb3_huri.
    levels = np.linspace(0, 1, 9)
    cdf = stats.norm.cdf(stats.norm.ppf(levels)[None, :] + beta[:, None])
    weights = np.diff(cdf, axis=-1)
    args = [th.tensor(a) for a in (atoms, targets, weights)]
    expected_target = np.mean((atoms.mean(axis=-1) - targets.mean(axis=-1)) ** 2)
    expected_distorted = np.mean((atoms.mean(axis=-1) - (weights * atoms).sum(axis=-1)) ** 2)
    assert expectation_loss(*args, reading="target").item() == pytest.approx(expected_target)
    assert expectation_loss(*args, reading="distorted").item() == pytest.approx(expected_distorted)
    with pytest.raises(ValueError, match="expectation loss"):
        expectation_loss(*args, reading="self")


def test_distorted_expectation_loss_is_a_spread_penalty_and_the_target_one_is_not():
    # The distorted reading only sees the prediction: its gradient narrows a spread distribution whatever the
    # targets, and it vanishes for a point mass. The target reading is zero when the means agree.
    atoms = th.linspace(-1.0, 1.0, 8, dtype=th.float64).expand(3, -1).clone().requires_grad_(True)
    weights = wang_weights(th.ones(3, dtype=th.float64), 8)
    expectation_loss(atoms, th.zeros(3, 5, dtype=th.float64), weights, "target").backward()
    assert atoms.grad.abs().max() == 0
    atoms.grad = None
    expectation_loss(atoms, th.zeros(3, 5, dtype=th.float64), weights, "distorted").backward()
    step = -atoms.grad[0]  # gradient descent direction
    assert step[0] > 0 and step[-1] < 0  # the lowest atom moves up, the highest down
    point_mass = th.full((3, 8), 2.0, dtype=th.float64)
    assert expectation_loss(point_mass, th.zeros(3, 5), weights, "distorted").item() == pytest.approx(0.0)


@pytest.mark.parametrize(("reading", "low", "high"), [("target", 0.96, 1.04), ("distorted", 0.0, 0.88)])
def test_fitted_spread_of_a_known_distribution_under_each_reading(reading, low, high):
    # study.analyses.expectation_fit (study/scripts/expectation_loss.py): free atoms
    # fitted to samples of N(2, 1.5^2) with the energy distance plus 0.05 x the expectation loss at beta = 1
    # (the paper's coefficient).
    from study.analyses.expectation_fit import fit_known_distribution

    mean, std = fit_known_distribution(reading, beta=1.0, coef=0.05, batch=16, steps=1000, seed=1)
    assert low * 1.5 <= std <= high * 1.5
    assert mean == pytest.approx(2.0, abs=0.08)


# --- RND novelty ----------------------------------------------------------------------------------------


def test_rnd_error_is_relative_to_the_variance_of_the_target_outputs():
    th.manual_seed(0)
    rnd = RandomNetworkDistillation(input_dim=5, output_dim=4)
    inputs = th.randn(4000, 5) * 3.0 + 1.0
    rnd.update_normalizer(inputs)
    with th.no_grad():
        normalized = (inputs.numpy() - inputs.numpy().mean(0)) / inputs.numpy().std(0)
        normalized = th.tensor(np.clip(normalized, -5, 5), dtype=th.float32)
        target = rnd.target(normalized).numpy().astype(np.float64)
        predicted = rnd.predictor(normalized).numpy().astype(np.float64)
    expected = ((predicted - target) ** 2).sum(axis=-1) / target.var(axis=0).sum()
    np.testing.assert_allclose(rnd.prediction_error(inputs).numpy(), expected, rtol=2e-3)
    raw = RandomNetworkDistillation(input_dim=5, output_dim=4, normalize_error=False)
    raw.load_state_dict(rnd.state_dict())
    assert not raw.normalize_error
    np.testing.assert_allclose(
        raw.prediction_error(inputs).numpy(), ((predicted - target) ** 2).mean(axis=-1), rtol=2e-3
    )


def test_rnd_error_starts_near_one_and_falls_on_familiar_states_only():
    th.manual_seed(0)
    rnd = RandomNetworkDistillation(input_dim=6)
    familiar = th.randn(2048, 6) * 0.5
    rnd.update_normalizer(familiar)
    novel = th.randn(2048, 6) * 0.5 + th.tensor([2.0, -2.0, 2.0, 0.0, 0.0, 0.0])
    before = rnd.prediction_error(familiar).mean().item()
    assert before > 1.0  # an untrained predictor misses the target by more than the target's own spread
    rnd.fit(familiar, n_epochs=30, batch_size=256)
    after, far = rnd.prediction_error(familiar).mean().item(), rnd.prediction_error(novel).mean().item()
    assert after < 0.2 * before
    assert far > 3 * after
    assert np.tanh(far) > 0.1


def test_rnd_state_saved_before_the_target_statistics_loads_with_unit_variance():
    rnd = RandomNetworkDistillation(input_dim=3)
    rnd.update_normalizer(th.randn(100, 3))
    state = rnd.state_dict()
    state["_extra_state"] = {key: state["_extra_state"][key] for key in ("mean", "var", "count")}
    old = RandomNetworkDistillation(input_dim=3)
    old.load_state_dict(state)
    np.testing.assert_array_equal(old.obs_rms.var, rnd.obs_rms.var)
    np.testing.assert_array_equal(old.target_rms.var, np.ones(16))
    inputs = th.randn(10, 3)
    with th.no_grad():
        normalized = old.normalize(inputs)
        expected = (old.predictor(normalized) - old.target(normalized)).pow(2).mean(dim=-1)
    th.testing.assert_close(old.prediction_error(inputs), expected, rtol=1e-5, atol=1e-7)


def test_energy_distance_of_presorted_atoms_skips_the_sorts_with_the_same_values_and_gradients():
    generator = th.Generator().manual_seed(3)
    x = th.sort(th.randn(6, 64, generator=generator), dim=-1).values.requires_grad_()
    y = th.sort(th.randn(6, 32, generator=generator) * 2.0 + 0.5, dim=-1).values
    presorted = energy_distance(x, y, presorted=True)
    (gradient,) = th.autograd.grad(presorted.sum(), x)
    reference = pairwise_energy_distance(x, y)
    (reference_gradient,) = th.autograd.grad(reference.sum(), x)
    th.testing.assert_close(presorted, reference, atol=1e-5, rtol=1e-5)
    th.testing.assert_close(gradient, reference_gradient, atol=1e-6, rtol=1e-5)
