"""A plain Gaussian MLP policy acts through the direct forward pass
(:func:`dss14_env.agents.policy.gaussian_mlp_actions`), bit for bit what its
stable-baselines3 ``predict(deterministic=True)`` gives; any other policy acts through
``predict``.
"""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy

from dss14_env.agents.policy import (
    POLICIES_DIR,
    gaussian_mlp_actions,
    is_gaussian_mlp,
    load_policy,
    shipped_policies,
)


@pytest.mark.parametrize("name", shipped_policies())
def test_the_direct_forward_pass_is_predict_bit_for_bit(name: str) -> None:
    ctrl = load_policy(POLICIES_DIR / name)
    assert ctrl.gaussian_mlp
    rng = np.random.default_rng(7)
    n_obs = ctrl.policy.observation_space.shape[0]
    # ordinary and saturating inputs (the clip to the action space acts on the latter)
    for scale in (0.5, 50.0):
        x = (scale * rng.standard_normal((33, n_obs))).astype(np.float32)
        expected, _ = ctrl.policy.predict(x, deterministic=True)
        got = gaussian_mlp_actions(ctrl.policy, x)
        assert got.dtype == expected.dtype and got.shape == expected.shape
        np.testing.assert_array_equal(got, expected)


def test_another_policy_class_acts_through_predict() -> None:
    class Custom(ActorCriticPolicy):
        pass

    box = spaces.Box(-1.0, 1.0, (3,), np.float32)
    assert is_gaussian_mlp(ActorCriticPolicy(box, box, lambda _: 0.0))
    assert not is_gaussian_mlp(Custom(box, box, lambda _: 0.0))
    assert not is_gaussian_mlp(ActorCriticPolicy(box, box, lambda _: 0.0, squash_output=True,
                                                 use_sde=True))
    assert not is_gaussian_mlp(ActorCriticPolicy(box, spaces.Discrete(3), lambda _: 0.0))


def test_a_config_whose_interface_does_not_fit_the_weights_is_refused_in_one_line(tmp_path) -> None:
    """A policy folder whose config builds an interface of another observation size than the
    weights take (its history lengthened) is refused, naming both sizes."""
    import shutil

    from dss14_env.agents.storage import PolicyFileError

    folder = tmp_path / "p"
    shutil.copytree(POLICIES_DIR / "ppo_residual_lqg", folder)
    cfg = folder / "config.yaml"
    text = cfg.read_text()
    assert "  history: 4\n" in text
    cfg.write_text(text.replace("  history: 4\n", "  history: 6\n"))
    with pytest.raises(PolicyFileError, match=r"gives \d+ observations, the weights expect \d+"):
        load_policy(folder)
