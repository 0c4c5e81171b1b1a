"""Write (or check) the generated parts of the README and the docs: the environments table, the results at a
glance and one page per registered environment (``mbs_envs.studies.generated``).

    python scripts/readme.py            # rewrite what changed
    python scripts/readme.py --check    # exit 1 naming the stale files
"""

import argparse
import pathlib
import sys

from mbs_envs.studies import generated

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if a generated file is stale")
    args = parser.parse_args(argv)
    if args.check:
        bad = generated.stale(ROOT)
        for p in bad:
            print(f"stale: {p.relative_to(ROOT)}")
        return 1 if bad else 0
    for p in generated.write(ROOT):
        print(f"wrote {p.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
