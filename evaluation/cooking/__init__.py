"""The cooking experiment (paper §4.4, `coexist eval --suite cooking`).

| module    | what                                                                          |
|-----------|-------------------------------------------------------------------------------|
| `suite`   | paired kitchen episodes per method and recipe pair, their statistics and GIFs |
| `report`  | the files of `reports/cooking` and the cooking section of the paper report    |
| `command` | `coexist eval --suite cooking`: the options, the run, the report              |
"""
