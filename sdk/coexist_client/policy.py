"""`RemotePolicy`: a running coexist server as the policy of one agent of a PettingZoo env.

    from coexist_client import Client, RemotePolicy
    client = Client("http://127.0.0.1:8000")
    goals = ["TomatoLettuceSalad", "CarrotBanana"]              # every agent's goal, in order
    cook = RemotePolicy(client, "cooking", goals, agent=0, infer=True, seed=0)
    action = cook(observations["agent_0"])                      # each step; cook.reset() per episode

The agent's observation from the env is already its own view (itself first, the others in
agent order), which is what the server takes: partner k of the env is index k + 1 of agent i's
observation where k < i, else k. Partners' goals are announced (`goals`) or, with `infer=True`,
inferred by the server from their actions (pass `observed={k: action}`, keyed by env agent
index, when the env tells them; otherwise the server recovers them from consecutive
observations where the environment allows it). With `method="sl"` the agent follows its own task
policy and no partner is sent. Each episode is one SDK episode (`Client.episode`): step t is
seeded with seed + t, over HTTP and gRPC alike. `last` holds the server's whole answer (`Action`:
probabilities, diagnostics, beliefs, models).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from coexist_client.client import Client
from coexist_client.sessions import Session
from coexist_client.types import Action


class RemotePolicy:
    """One agent of a PettingZoo env, acting through a server; see the module docstring."""

    def __init__(
        self,
        client: Client,
        env: str,
        goals: Sequence[str],
        agent: int = 0,
        *,
        method: str = "aail_bounded",
        infer: bool = False,
        seed: int | None = None,
        greedy: bool = False,
        alias: str = "production",
        regret_bound: float | None = None,
        budget: float | None = None,
        temperature: float | None = None,
    ) -> None:
        if not 0 <= agent < len(goals):
            raise ValueError(f"agent: expected 0..{len(goals) - 1}, got {agent}")
        self.client, self.env, self.goal, self.agent = client, env, goals[agent], agent
        others = [k for k in range(len(goals)) if k != agent]
        # env agent k -> its index in this agent's observation (itself first, others in order)
        self.partner_index = {k: j + 1 for j, k in enumerate(others)}
        self.partners: dict[int, str | None] = {}
        if method != "sl":
            self.partners = {self.partner_index[k]: None if infer else goals[k] for k in others}
        self.settings: dict[str, Any] = {
            "method": method,
            "alias": alias,
            "regret_bound": regret_bound,
            "temperature": temperature,
        }
        if budget is not None:  # aail_budget's budget B; the episode carries what it spent
            self.settings["budget"] = budget
        self.greedy = greedy
        self.seed = seed
        self.last: Action | None = None
        self._episode: Session | None = None

    def reset(self, seed: int | None = None) -> None:
        """End the current episode; the next `act` opens a new one (seeded with `seed`, else the
        constructor's)."""
        self.close()
        if seed is not None:
            self.seed = seed

    def act(self, observation: Any, observed: Mapping[int, int | None] | None = None) -> int:
        """The action for this step's observation (sampled, or greedy with `greedy=True`);
        `observed`: partners' last actions by env agent index (inferred partners only)."""
        if self._episode is None:
            self._episode = self.client.episode(
                self.env, self.goal, partners=self.partners, seed=self.seed, **self.settings
            )
        inferred = [j for j, goal in self.partners.items() if goal is None]
        seen = None
        if observed is not None and inferred:
            seen = {self.partner_index[k]: a for k, a in observed.items() if k != self.agent}
        self.last = self._episode.act(observation, observed=seen)
        return self.last.greedy_action if self.greedy else self.last.action

    __call__ = act

    def close(self) -> None:
        if self._episode is not None:
            self._episode.close()
            self._episode = None
