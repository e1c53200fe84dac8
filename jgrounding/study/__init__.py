"""The paper's user study (Sec. IV-B) as a tool: design it, run it with people on the policy server, store
every rating in a database, analyse it, and validate all of that with simulated participants (docs/study.md).

``python -m jgrounding.study serve --design study.toml`` serves the operator's page (``/study/operator``) and the
participant's (``/study/participant?p=ID``); ``analyze DB`` writes the report and the figure; ``export DB``
writes CSV and Parquet with a data dictionary; ``simulate URL`` runs simulated participants through a running server.

The modules, in the order they build on each other:

- :mod:`jgrounding.study.design`: :class:`Design` (conditions, episodes, questionnaire) from a TOML file;
- :mod:`jgrounding.study.latin`: :func:`williams`, the balanced Latin square that orders the conditions;
- :mod:`jgrounding.study.store`: :class:`Store`, the SQLAlchemy Core tables (SQLite or PostgreSQL);
- :mod:`jgrounding.study.export`: :func:`export` to CSV / Parquet and the data dictionary;
- :mod:`jgrounding.study.analysis`: Wilson intervals, paired tests with Holm, effect sizes, order, power, figure;
- :mod:`jgrounding.study.simulate`: simulated participants and :func:`validate` of the analysis;
- :mod:`jgrounding.study.app`: :class:`StudyServer`, the pages, their API and the study's live stream;
- :mod:`jgrounding.study.visit`: simulated participants through a running server's API (``simulate URL``);
- :mod:`jgrounding.study.__main__`: the command line and :func:`serve`.
"""

from jgrounding.study.design import CONDITIONS, DIMENSIONS, Design, DesignError, Episode, Question, load_design
from jgrounding.study.latin import order_for, williams

_LAZY = {
    "Store": ("jgrounding.study.store", "Store"),
    "StudyError": ("jgrounding.study.store", "StudyError"),
    "database_url": ("jgrounding.study.store", "database_url"),
    "StudyServer": ("jgrounding.study.app", "StudyServer"),
    "export": ("jgrounding.study.export", "export"),
    "analyze": ("jgrounding.study.analysis", "analyze"),
    "validate": ("jgrounding.study.simulate", "validate"),
    "serve": ("jgrounding.study.__main__", "serve"),
}


def __getattr__(name):  # the store, the server and the exports import sqlalchemy, starlette, pyarrow: on use
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'jgrounding.study' has no attribute {name!r}")


__all__ = [
    "CONDITIONS",
    "DIMENSIONS",
    "Design",
    "DesignError",
    "Episode",
    "Question",
    "load_design",
    "order_for",
    "williams",
    *_LAZY,
]
