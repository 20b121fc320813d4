"""Shared fixtures: a fresh build cache per test session, compilers, helpers."""

import os
import shutil
import tempfile

import pytest

# One private cache per session: builds are reused between tests, never from an earlier run.
os.environ.setdefault("LAGCODEGEN_CACHE", tempfile.mkdtemp(prefix="lagcodegen-test-cache-"))


@pytest.fixture(scope="session")
def cc():
    compiler = os.environ.get("CC", "cc")
    if shutil.which(compiler) is None:
        pytest.fail(f"C compiler {compiler!r} not found: install gcc")
    return compiler


@pytest.fixture(scope="session")
def tools():
    """make, cmake, gcc and gfortran, which the bundle tests build with."""
    missing = [tool for tool in ("make", "cmake", "gcc", "gfortran") if shutil.which(tool) is None]
    if missing:
        pytest.fail(f"bundle tests need {', '.join(missing)}")


@pytest.fixture(scope="session")
def fc():
    if shutil.which("gfortran") is None:
        pytest.fail("gfortran not found: apt-get install gfortran")
    return "gfortran"
