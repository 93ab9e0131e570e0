"""The native co-simulation servers' C++ (package data under gateware/native/): found through
the package's resources, and every placeholder the Python side fills is in its template."""

import re
import tomllib
from pathlib import Path

from navgate.gateware import native_axi, native_stream


def test_templates_are_package_data_and_complete():
    axi = native_axi._server_template()
    assert "int main" in axi and '#include "V@TOP@.h"' in axi
    placeholders = set(re.findall(r"@[A-Z_]+@", axi))
    assert placeholders == {"@TOP@", "@N_STREAMS@", "@N_WATCH@", "@MAX_WORDS@",
                            "@STREAM_WIDTHS@", "@ADDR_MASK@", "@SET_VALID@", "@GET_READY@",
                            "@SET_PAYLOAD@", "@GET_WATCH@"}
    stream = native_stream._server_template()
    assert "int main" in stream and set(re.findall(r"%\((\w+)\)", stream)) >= {"top"}
    pyproject = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    assert "**/*.cpp" in pyproject["tool"]["setuptools"]["package-data"]["navgate"]
