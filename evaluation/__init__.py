"""The experiments: their statistics, plots and reports (`coexist eval --suite ...`).

One folder per suite (`paper/`: the particle experiments, §4.2; `inference/`: online goal
inference; `cooking/`: the kitchen, §4.4; `partners/`: partners not coexist's; `pairs/`: every
method on goal pairs of any registered environment), each with a `command.py` implementing `base.Suite`,
over the parts they share:

| module       | what                                                                       |
|--------------|----------------------------------------------------------------------------|
| `base`       | `Suite`, what a suite implements, and `EvalOptions`, the CLI's options     |
| `suites`     | the suites by name (`coexist eval --suite NAME`): `coexist.suites` plugins |
| `config`     | scenarios, methods, episode counts and seeds of the particle suite          |
| `backend`    | action distributions from the in-process engine or a server (SDK)          |
| `rollout`    | paired, vectorised episodes in one batched world (common random numbers)   |
| `stats`      | mean ± SE, Wilcoxon signed-rank, exact McNemar, per-method summaries        |
| `targets`    | the report's numeric targets and their verdicts                            |
| `timing`     | `python -m evaluation.timing --log F -- cmd`: wall time of training runs   |
| `prepare`    | a tiny zoo trained on the fly for `--fast`                                 |
"""
