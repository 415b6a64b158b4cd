"""One soft-Q update on a tiny batch; the target of eq. 5; the replay buffer."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from policy.maths import soft_value
from policy.qnet import QNetSpec, QNetwork
from trainer.replay import Batch, StackedReplay
from trainer.soft_q import StackedSoftQ, soft_q_target

SPEC = QNetSpec(obs_dim=8, n_actions=5, hidden=(16, 16))


def _batch(n_nets: int = 3, size: int = 4, seed: int = 0) -> Batch:
    g = torch.Generator().manual_seed(seed)
    return Batch(
        obs_GBD=torch.rand(n_nets, size, 8, generator=g),
        act_GB=torch.randint(0, 5, (n_nets, size), generator=g),
        rew_GB=-torch.rand(n_nets, size, generator=g),
        next_obs_GBD=torch.rand(n_nets, size, 8, generator=g),
    )


def test_soft_q_target_matches_eq5_by_hand() -> None:
    q = torch.tensor([[[0.0, math.log(2.0) * 0.5, 0.0, 0.0, 0.0]]], dtype=torch.float64)
    target = soft_q_target(torch.tensor([[1.0]], dtype=torch.float64), q, gamma=0.9, alpha=0.5)
    # V = α log Σ exp(Q/α) = 0.5 log(4 + 2) ; target = r + γ V
    assert torch.allclose(
        target, torch.tensor([[1.0 + 0.9 * 0.5 * math.log(6.0)]], dtype=torch.float64)
    )
    np.testing.assert_allclose(soft_value(q.numpy()[0], 0.5), [0.5 * math.log(6.0)], rtol=1e-12)


def test_update_gives_finite_loss_and_keeps_target_until_copy() -> None:
    learner = StackedSoftQ(
        SPEC, 3, lr=1e-2, gamma=0.9, alpha=0.05, generator=torch.Generator().manual_seed(1)
    )
    target_before = {k: v.clone() for k, v in learner.target.state_dict().items()}
    online_before = {k: v.clone() for k, v in learner.online.state_dict().items()}
    stats = learner.update(_batch())
    assert stats.loss_G.shape == (3,) and stats.q_mean_G.shape == (3,)
    assert torch.isfinite(stats.loss_G).all() and (stats.loss_G > 0).all()
    for k, v in learner.target.state_dict().items():
        assert torch.equal(v, target_before[k]), f"target {k} moved before the copy"
    assert any(not torch.equal(v, online_before[k]) for k, v in learner.online.state_dict().items())
    learner.sync_target()
    for k, v in learner.target.state_dict().items():
        assert torch.equal(v, learner.online.state_dict()[k])


def test_networks_learn_independently() -> None:
    """Member 0's gradient must not depend on member 1's data (the stacked loss is a sum)."""
    a = StackedSoftQ(
        SPEC, 2, lr=1e-2, gamma=0.9, alpha=0.05, generator=torch.Generator().manual_seed(3)
    )
    b = StackedSoftQ(
        SPEC, 2, lr=1e-2, gamma=0.9, alpha=0.05, generator=torch.Generator().manual_seed(3)
    )
    batch = _batch(2)
    other = Batch(
        obs_GBD=torch.cat([batch.obs_GBD[:1], torch.rand(1, 4, 8)]),
        act_GB=torch.cat([batch.act_GB[:1], torch.zeros(1, 4, dtype=torch.long)]),
        rew_GB=torch.cat([batch.rew_GB[:1], torch.full((1, 4), 100.0)]),
        next_obs_GBD=torch.cat([batch.next_obs_GBD[:1], torch.rand(1, 4, 8)]),
    )
    a.update(batch)
    b.update(other)
    for k in a.online.member_state(0):
        assert torch.allclose(a.online.member_state(0)[k], b.online.member_state(0)[k], atol=1e-7)
    assert not torch.allclose(
        a.online.member_state(1)["layers.2.bias"], b.online.member_state(1)["layers.2.bias"]
    )


def test_act_is_seeded_and_in_range() -> None:
    def run() -> torch.Tensor:
        learner = StackedSoftQ(
            SPEC, 2, lr=1e-3, gamma=0.9, alpha=0.05, generator=torch.Generator().manual_seed(7)
        )
        return learner.act(torch.rand(2, 6, 8, generator=torch.Generator().manual_seed(0)))

    first, second = run(), run()
    assert first.shape == (2, 6) and first.min() >= 0 and first.max() < 5
    assert torch.equal(first, second)


def test_replay_ring_buffer_overwrites_oldest_and_samples_per_network() -> None:
    replay = StackedReplay(2, capacity=5, obs_dim=1)
    for step in range(3):
        obs = torch.full((2, 2, 1), float(step))
        obs[1] += 100.0  # network 1's transitions are distinguishable from network 0's
        replay.add(
            obs, torch.zeros(2, 2, dtype=torch.long), torch.full((2, 2), float(step)), obs + 0.5
        )
    assert replay.size == 5
    # 6 transitions were added to a capacity of 5: the oldest (step 0, first env) is gone
    assert sorted(replay.rew_GC[0].tolist()) == [0.0, 1.0, 1.0, 2.0, 2.0]
    batch = replay.sample(64, torch.Generator().manual_seed(0))
    assert batch.obs_GBD.shape == (2, 64, 1)
    assert (batch.obs_GBD[0] < 100).all() and (batch.obs_GBD[1] >= 100).all()
    assert torch.allclose(batch.next_obs_GBD - batch.obs_GBD, torch.full((2, 64, 1), 0.5))


def test_each_network_gets_its_own_losss_gradient() -> None:
    """The stacked update's gradient equals, member by member, the gradient of that member's own
    loss (eq. 4) taken through a plain `QNetwork` on its own samples; a second call sets the same
    gradient again (it does not add to the first)."""
    learner = StackedSoftQ(
        SPEC, 3, lr=1e-3, gamma=0.9, alpha=0.05, generator=torch.Generator().manual_seed(5)
    )
    batch = _batch(3, size=32)
    with torch.no_grad():
        target_GB = soft_q_target(
            batch.rew_GB, learner.target(batch.next_obs_GBD), learner.gamma, learner.alpha
        )
    stats = learner.set_gradients(batch)
    stats_again = learner.set_gradients(batch)
    assert torch.equal(stats.loss_G, stats_again.loss_G)
    grads = {name: p.grad for name, p in learner.online.named_parameters()}
    for g in range(3):
        net = QNetwork(SPEC)
        net.load_state_dict(learner.online.member_state(g))
        q_B = net(batch.obs_GBD[g]).gather(1, batch.act_GB[g].unsqueeze(-1)).squeeze(-1)
        loss = 0.5 * (q_B - target_GB[g]).pow(2).mean()
        loss.backward()
        assert math.isclose(stats.loss_G[g].item(), loss.item(), rel_tol=1e-6)
        assert math.isclose(stats.q_mean_G[g].item(), q_B.mean().item(), rel_tol=1e-6)
        for k, layer in enumerate(net.layers):
            for kind, theirs in (("weights", layer.weight.grad), ("biases", layer.bias.grad)):
                mine = grads[f"{kind}.{k}"]
                assert mine is not None and theirs is not None
                torch.testing.assert_close(mine[g], theirs, rtol=1e-5, atol=1e-7, msg=f"{kind}.{k}")


def test_an_ending_transition_is_not_bootstrapped_and_a_time_limit_is() -> None:
    """Eq. 5 stops at the environment's ending (r alone) and bootstraps everywhere else; a
    replay that records endings hands them to the update, and refuses a step without them."""
    q = torch.tensor([[[0.0, 1.0], [0.5, 0.0]]], dtype=torch.float64)
    rew = torch.tensor([[1.0, 2.0]], dtype=torch.float64)
    ended = torch.tensor([[1.0, 0.0]], dtype=torch.float64)
    got = soft_q_target(rew, q, gamma=0.9, alpha=0.5, ended_GB=ended)
    plain = soft_q_target(rew, q, gamma=0.9, alpha=0.5)
    assert got[0, 0] == 1.0 and got[0, 1] == plain[0, 1]

    replay = StackedReplay(1, 8, 8, endings=True)
    obs = torch.zeros(1, 2, 8)
    replay.add(
        obs,
        torch.zeros(1, 2, dtype=torch.long),
        torch.zeros(1, 2),
        obs,
        torch.tensor([[True, False]]),
    )
    batch = replay.sample(64, torch.Generator().manual_seed(0))
    assert batch.ended_GB is not None and set(batch.ended_GB.unique().tolist()) == {0.0, 1.0}
    with pytest.raises(ValueError, match="ended_GE"):
        replay.add(obs, torch.zeros(1, 2, dtype=torch.long), torch.zeros(1, 2), obs)
    plain_replay = StackedReplay(1, 8, 8)
    plain_replay.add(obs, torch.zeros(1, 2, dtype=torch.long), torch.zeros(1, 2), obs)
    assert plain_replay.sample(4, torch.Generator().manual_seed(0)).ended_GB is None
