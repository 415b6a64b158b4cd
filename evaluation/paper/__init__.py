"""The paper's particle experiments (§4.2, `coexist eval --suite paper`).

| module       | what                                                                       |
|--------------|----------------------------------------------------------------------------|
| `pairs`      | the random sample of goal pairs, tested over pairs                         |
| `claims`     | the paper's claims 1-4 as checks with fixed thresholds                     |
| `scaling`    | networks each method needs; training cost from lineage and the timing log  |
| `directions` | Fig. 6: expected acceleration over a grid of ego positions                 |
| `plots`      | the figures (matplotlib)                                                   |
| `tables`     | markdown tables                                                            |
| `report`     | REPORT.md, results.json and the figures                                    |
| `suite`      | everything in order                                                        |
| `command`    | `coexist eval --suite paper`: the options, the run, the report             |
"""
