"""stereo_classic: classical stereo matching (numba SGM), file I/O, datasets, and object localisation.

Each block below belongs to one module; the public names are listed in ``__all__``.
"""

__version__ = "0.1.0"

__all__: list[str] = ["__version__"]
