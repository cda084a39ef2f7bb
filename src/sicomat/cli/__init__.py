"""The ``sicomat`` command-line program: a thin shell over the public API."""
