#!/usr/bin/env python3
"""Counts test cases in the JUnit XML files under a results folder (gtest and rostest both write them) and prints
the closing line CI reads: 'N passed, N failed, N skipped'. catkin_test_results gives the verdict; its own totals
count suites and cases alike, so they are not used for the line."""
import pathlib
import sys
import xml.etree.ElementTree as ElementTree

root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "build/test_results")
passed = failed = skipped = 0
for path in sorted(root.rglob("*.xml")):
    try:
        cases = ElementTree.parse(path).getroot().iter("testcase")
    except ElementTree.ParseError as error:
        print(f"{path}: unreadable ({error})", file=sys.stderr)
        failed += 1
        continue
    for case in cases:
        if case.find("failure") is not None or case.find("error") is not None:
            failed += 1
        elif case.find("skipped") is not None or case.get("status") == "notrun":
            skipped += 1
        else:
            passed += 1
print(f"{passed} passed, {failed} failed, {skipped} skipped")
sys.exit(0 if passed + failed > 0 else 1)
