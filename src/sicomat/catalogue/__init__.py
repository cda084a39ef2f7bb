"""The component catalogue (issue 12): schemas of the part kinds, the shipped data files and their loader.

Layer: beside ``description`` (it imports only the foundation and ``description``)."""
