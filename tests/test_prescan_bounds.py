"""The pre-scan's largest row and column (fleetrun/workbook/xlsx_safety.py) found from a chunk's
ends and confirmed by one search are exactly the largest of every reference in the chunk (the
reference: the list of all of them), in order or not, with leading zeros, lower-case letters and
references far from the ends."""
from __future__ import annotations

import random

from fleetrun.workbook import xlsx_safety as X


def _every(text: bytes, n_values, pattern, order):
    for n in n_values:
        found = set(pattern(n, True).findall(text))
        if found:
            return max(order(x) for x in found)
    return None


def _fast(text: bytes, n_values, pattern, above, order):
    for n in n_values:
        found = X._largest(text, pattern(n, True), above, order)
        if found is not None:
            return order(found)
    return None


def test_largest_reference_equals_the_largest_of_all():
    rng = random.Random(3)
    for _ in range(1500):
        refs = []
        for _ in range(rng.randint(1, 40)):
            letters = "".join(rng.choice("ABCXYZabcxyz") for _ in range(rng.choice([1, 2, 2, 3])))
            number = str(rng.choice([rng.randint(1, 999_999), rng.randint(100_000, 999_999),
                                     rng.randint(1_000_000, 1_048_576)]))
            refs.append(f'<c r="{letters}{"00" if rng.random() < 0.1 else ""}{number}"><v>1</v></c>')
        middle = "x" * rng.choice([0, 10, 2 * X.WINDOW_BYTES])
        text = ("".join(refs[:len(refs) // 2]) + middle + "".join(refs[len(refs) // 2:])).encode()
        assert _fast(text, (7, 6), X._digits, X._digits_above, int) == _every(text, (7, 6), X._digits, int)
        assert (_fast(text, (3, 2), X._letters, X._letters_above, X._column_of)
                == _every(text, (3, 2), X._letters, X._column_of))


def test_a_larger_reference_in_the_middle_is_found():
    rows = b"".join(b'<row r="%d"><c r="A%d"/></row>' % (r, r) for r in range(100_000, 104_000))
    text = rows[:len(rows) // 2] + b'<c r="AZ999999"/>' + rows[len(rows) // 2:]
    assert int(X._largest(text, X._digits(6, True), X._digits_above, int)) == 999_999
    assert X._column_of(X._largest(text, X._letters(2, True), X._letters_above, X._column_of)) == 52


def test_started_cells_and_rows_equal_a_count_of_every_start():
    """The tag counts (one ``bytes.count`` and one search where the text allows) equal the count of
    every ``<c`` / ``<row`` followed by a space, ``>``, ``/`` or a line break: with ``<cols>``,
    ``<col .../>``, ``<cfRule``, bare ``<c>`` and ``<c/>`` cells, prefixed tags and line breaks."""
    import re

    rng = random.Random(5)
    pieces = ['<c r="A1"><v>1</v></c>', "<c><v>2</v></c>", "<c/>", '<c\nr="B2"/>', "<c\tt=\"s\"/>",
              "<cols>", '<col min="1" max="2"/>', "</cols>", '<cfRule type="x"/>', "<colBreaks/>",
              '<row r="3">', "<row>", "</row>", "<rowBreaks/>", '<x:c r="C3"/>', '<x:row r="4">', "text <co"]
    for _ in range(500):
        text = "".join(rng.choice(pieces) for _ in range(rng.randint(0, 30))).encode()
        cells = len(re.findall(rb"<c[ >/\n\t\r]", text)) + len(re.findall(rb"<\w+:c[\s/>]", text))
        rows = len(re.findall(rb"<row[ >/\n\t\r]", text)) + len(re.findall(rb"<\w+:row[\s/>]", text))
        assert X._count_tags(text) == (cells, rows), text


def test_holds_equals_in():
    """``_holds`` (the pre-scan's search for a namespace prefix or a formula tag by its rare byte)
    answers as ``in`` does: with the rare byte absent, present without the pattern, at the text's
    start and end, and more often than RARE_TRIES (where it searches as ``in`` does)."""
    rng = random.Random(7)
    pieces = ["<c r=\"A1\">", "<f>", "</f>", "<x:c/>", "<x:row>", ":", "f", "<", "c", "row", "x:f", "<v>1</v>",
              "ff" * (X.RARE_TRIES // 2), ":" * (X.RARE_TRIES + 1)]
    for _ in range(2000):
        text = "".join(rng.choice(pieces) for _ in range(rng.randint(0, 12))).encode()
        assert X._holds(text, (b":c", b":row")) == (b":c" in text or b":row" in text), text
        assert X._holds(text, (b"<f",), rare=1) == (b"<f" in text), text
        assert X._holds(text, (b":f",)) == (b":f" in text), text
