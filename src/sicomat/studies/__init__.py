"""Parameter studies (issue 14): many variants of a machine model, one results table."""
