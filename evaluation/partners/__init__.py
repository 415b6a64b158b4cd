"""`coexist eval --suite partners`: every method against partners that are not coexist's own."""
