"""The component database (issue 12, ``docs/catalogue.md``): the shipped entries (``data/``), the loader with
user folders and filters (``store``), and the look-up of a model file's part ids (``resolve``). The part
schemas and the drive-train rules are in :mod:`sicomat.description` (``parts``, ``drivetrain``,
``components``, ``chain``).

Layer: above ``description``, below ``io`` (the model-file loader resolves ids with it)."""

from .store import Catalogue, Entry, load_catalogue
from .resolve import resolve_parts, use_folders

__all__ = ["Catalogue", "Entry", "load_catalogue", "resolve_parts", "use_folders"]
