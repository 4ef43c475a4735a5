"""The paper's Tables 1 and 2 (REFERENCE.md protocol) through the real HTTP service.

The protocol lives in `harness.paper` (its docstring describes the rows, the dense
check and the columns); this script runs it in full and writes bench/../artifacts/.

    python bench/paper_tables.py [--smoke] [--seed S] [--postgres URL] [--calls N]
                                 [--rows KEYS] [--unpaired] [--json PATH] [--chart PATH]
"""

from __future__ import annotations

from pathlib import Path

from harness.paper import main

if __name__ == "__main__":
    main(artifacts=Path(__file__).resolve().parent.parent / "artifacts")
