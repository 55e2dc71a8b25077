"""Reading a result table (a store's ``summary.csv``, a study's table) with its identifier
columns kept as text.

``pd.read_csv`` guesses a column's type from its values, so a hex identifier made of digits
around one ``e`` (the run id ``164025082e33``, a fingerprint ``4233509498e41b07``) reads as a
float, and one made of digits only loses its leading zeros. A table read that way no longer
matches its own meta data or the fingerprints another table recorded.
"""

from __future__ import annotations

import pandas as pd

#: columns of the result tables that hold hex identifiers
ID_COLUMNS = {"run_id": str, "fingerprint": str}


def read_table(source, **kwargs) -> pd.DataFrame:
    """A result table as ``pd.read_csv`` reads it, its :data:`ID_COLUMNS` kept as text.

    Parameters
    ----------
    source : str, Path or file-like
        The CSV file.
    **kwargs
        Passed to ``pd.read_csv``; a ``dtype`` mapping is merged with :data:`ID_COLUMNS`.
    """
    return pd.read_csv(source, dtype={**ID_COLUMNS, **kwargs.pop("dtype", {})}, **kwargs)
