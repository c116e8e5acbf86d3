"""Repository-wide pytest set-up: the ``--renderer`` option that narrows the conformance suite.

``pytest --renderer warp`` (repeatable) runs ``tests/conformance`` against the named backends only;
the default is every backend found through the ``cerberus.renderers`` entry points. The environment
variable ``CERBERUS_RENDERERS=warp,torch`` does the same where the command line is not at hand.
"""
from __future__ import annotations


def pytest_addoption(parser) -> None:
    parser.addoption("--renderer", action="append", default=None, metavar="NAME",
                     help="run the renderer conformance suite against this backend only (repeatable; "
                     "default: every installed backend; env CERBERUS_RENDERERS=a,b does the same)")
