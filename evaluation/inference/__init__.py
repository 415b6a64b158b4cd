"""Online goal inference (`coexist eval --suite inference`).

| module     | what                                                              |
|------------|-------------------------------------------------------------------|
| `accuracy` | the belief over a partner's goal after k observed steps           |
| `value`    | what inferring instead of being told costs in return              |
| `suite`    | everything in order                                               |
| `tables`   | markdown tables                                                   |
| `plots`    | the figures (matplotlib)                                          |
| `report`   | the report's files and its section in the paper report            |
| `command`  | `coexist eval --suite inference`: the options, the run, the report |
"""
