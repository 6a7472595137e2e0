#!/usr/bin/python3
"""Each package README shows its compiled example verbatim, so the docs match the code.

Usage: readme_examples_test.py WORKSPACE
"""
import pathlib
import sys


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    problems = []
    checked = 0
    for example in sorted(pathlib.Path(sys.argv[1], "src").glob("*/examples/*.cpp")):
        readme = example.parent.parent / "README.md"
        if not readme.is_file():
            problems.append(f"{readme} is missing")
        elif example.read_text() not in readme.read_text():
            problems.append(f"{readme} does not show {example.name} as it is; paste it again")
        checked += 1
    for p in problems:
        print("README:", p)
    print(f"readme examples: {checked} checked,", "FAIL" if problems or not checked else "OK")
    return 1 if problems or not checked else 0


if __name__ == "__main__":
    sys.exit(main())
