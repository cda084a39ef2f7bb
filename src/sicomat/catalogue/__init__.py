"""The component catalogue and the drive-train rules (issue 12): schemas of the part kinds, the shipped data
files and their loader (``kinds``, ``store``), and the physics that lumps a chain of parts
(``drivetrain``, ``motor_checks``).

Layer: beside ``description`` (it imports only the foundation and ``description``)."""
