"""The `coexist` command line: one module per job, registered in `cli.main`."""
