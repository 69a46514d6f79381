"""conftest.py - makes rbx1proto importable and loads the shared vectors for the Python tests."""
import json
import os
import sys

import pytest

PROTOCOL_DIR = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(PROTOCOL_DIR, "python"))


def load_vectors(name):
    with open(os.path.join(PROTOCOL_DIR, "vectors", name)) as f:
        return json.load(f)["vectors"]


@pytest.fixture(scope="session")
def vectors():
    return load_vectors
