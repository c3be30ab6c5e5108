"""Files: pickle-free save and load of splines (:mod:`.files`, NumPy ``.npz``), G+Smo XML (:mod:`.gismo`) and
IGES 5.3 (:mod:`.iges`), every write atomic."""

from geometry.io.files import atomic_write, load, load_all, save, save_all

__all__ = ["atomic_write", "load", "load_all", "save", "save_all"]
