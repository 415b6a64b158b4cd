"""The model store's tests. This folder is on `sys.path` for every test below it (pytest puts a
conftest's folder there), so `store_fixtures` (the SQLite and PostgreSQL store URLs) is imported
by its bare name from `sql/` too."""
