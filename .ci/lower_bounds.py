"""Print a pip constraints file pinning every ``>=`` bound of pyproject.toml to that version.

Installing with it (``pip install -c FILE -e ".[test,highway]"``) gives the oldest
versions the project says it supports, so the lower bounds are tested, not assumed.
"""

import re
import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    sys.exit("lower_bounds.py needs Python >= 3.11 (tomllib)")

project = tomllib.loads(
    Path(__file__).resolve().parent.parent.joinpath("pyproject.toml").read_text()
)["project"]
extras = sys.argv[1].split(",") if len(sys.argv) > 1 else []
requirements = list(project["dependencies"])
for extra in extras:
    requirements += project["optional-dependencies"][extra]
for req in requirements:
    match = re.fullmatch(r"([A-Za-z0-9_.\-]+)(\[[^\]]*\])?\s*>=\s*([0-9][^,;\s]*)\s*", req)
    if not match:
        sys.exit(f"pyproject.toml: {req!r} has no plain '>=' lower bound")
    print(f"{match.group(1)}=={match.group(3)}")
