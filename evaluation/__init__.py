"""The paper's experiments, their statistics, plots and report (`coexist eval --suite paper`).

| module       | what                                                                       |
|--------------|----------------------------------------------------------------------------|
| `config`     | scenarios, methods, episode counts and seeds of the particle suite          |
| `backend`    | action distributions from the in-process engine or a server (SDK)          |
| `rollout`    | paired, vectorised episodes in one batched world (common random numbers)   |
| `stats`      | mean ± SE, Wilcoxon signed-rank, exact McNemar, per-method summaries        |
| `pairs`      | the random sample of goal pairs, tested over pairs                         |
| `claims`     | the paper's claims 1-4 as checks with fixed thresholds                     |
| `scaling`    | networks each method needs; training cost from lineage and the timing log  |
| `timing`     | `python -m evaluation.timing --log F -- cmd`: wall time of training runs   |
| `directions` | Fig. 6: expected acceleration over a grid of ego positions                 |
| `plots`      | the figures (matplotlib)                                                   |
| `tables`     | markdown tables                                                            |
| `report`     | REPORT.md, results.json and the figures                                    |
| `suite`      | everything in order                                                        |
| `prepare`    | a tiny zoo trained on the fly for `--fast`                                 |
| `cooking`    | the cooking experiment (§4.4)                                              |
| `inference*` | online goal inference (issue 9): accuracy vs k, value, report              |
"""
