"""Print one of the two commands at the top of README.md ("main" or "test")."""

import re
import sys
from pathlib import Path

text = Path(__file__).resolve().parent.parent.joinpath("README.md").read_text()
block = re.search(r"```(?:bash|sh)\n(.*?)```", text, re.S)
if not block:
    sys.exit("README.md has no fenced shell block")
lines = [line for line in block.group(1).splitlines() if line.strip()]
if len(lines) != 2:
    sys.exit(f"README.md's first shell block must hold exactly two commands, found {len(lines)}")
which = sys.argv[1] if len(sys.argv) > 1 else "test"
print(lines[0] if which == "main" else lines[1])
