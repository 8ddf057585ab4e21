#!/usr/bin/env python3
"""Checks that no function in engine/ or materials/ is longer than 100 lines unless it says why.

Usage: check_function_length.py REPO_ROOT [--all]
  (the ctest "functions are short or say why they are long"; docs/architecture.md)

A function's length runs from the first line of its signature (after any `template <...>`
line, which belongs to it) to its closing brace, both included. Everything inside a function's
braces is part of it: lambdas, local classes and nested blocks count toward the enclosing
function. Namespace, class, struct, union and enum bodies and brace initializers are not
functions; the functions defined inside a class body are.

A function longer than LIMIT lines passes only if the comment block right above it (the
contiguous `//` or `/* */` lines before its signature) contains the words "long because",
followed by the reason, e.g.

  /// ... Long because it is the SIMD gather's hot loop: split, the compiler ...

Every other long function is printed as

  FILE:LINE: NAME is N lines (limit 100); split it by job or say "long because ..." above it

and the script exits 1; with none it exits 0. The documented long functions are listed on
stderr (with --all also every function over half the limit). The parser matches braces after
blanking comments, string and character literals (raw strings included) and preprocessor lines;
both branches of an #if are read, so each branch must balance its braces (they do). Stdlib only.
"""

import os
import re
import sys

from source_tree import source_files

LIMIT = 100
MARKER = "long because"
SCANNED_ROOTS = ("engine", "materials")

# A function head ends with its parameter list's `)`, then any qualifiers, a noexcept(...),
# a trailing return type, or an all-capitals attribute macro (HWY_ATTR).
QUALIFIERS = (r"(?:\s|const\b|volatile\b|noexcept\b|override\b|final\b|mutable\b|&"
              r"|[A-Z_][A-Z0-9_]*\b)*")
FUNCTION_TAIL_RE = re.compile(
    r"\)" + QUALIFIERS + r"(?:noexcept\s*\([^()]*\)" + QUALIFIERS + r")?(?:->[^;{}]*)?$")
CLASS_RE = re.compile(
    r"^(?:(?:typedef|static|inline|constexpr|const)\s+)*(?:class|struct|union|enum)\b")
ACCESS_RE = re.compile(r"^\s*(?:public|private|protected)\s*:(?!:)")
TEMPLATE_RE = re.compile(r"^\s*template\s*<")
IDENT_END_RE = re.compile(r"[A-Za-z0-9_>]\s*$")
NAME_RE = re.compile(r"([~A-Za-z_][A-Za-z0-9_:~<>]*(?:operator\s*[^\s(]+)?)\s*\($")


def blank_code(text):
    """`text` with comments, string and character literals and preprocessor lines replaced by
    spaces (newlines kept, so offsets and line numbers stay)."""
    out = list(text)
    i, n = 0, len(text)
    line_start = True

    def blank(a, b):
        for k in range(a, b):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = text[i]
        if line_start and c in " \t":
            i += 1
            continue
        if line_start and c == "#":
            # A preprocessor line, with its backslash continuations.
            j = i
            while j < n:
                if text[j] == "\n" and text[j - 1] != "\\":
                    break
                j += 1
            blank(i, j)
            i = j
            continue
        line_start = c == "\n"
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            blank(i, j)
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            blank(i, j)
            i = j
        elif (c == "R" and text.startswith('"', i + 1)
              and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_"))):
            m = re.match(r'R"([^()\\ ]{0,16})\(', text[i:])
            if not m:
                i += 1
                continue
            end = text.find(")" + m.group(1) + '"', i + m.end())
            j = n if end < 0 else end + len(m.group(1)) + 2
            blank(i + 1, j - 1)
            i = j
        elif c in "\"'":
            if c == "'" and i > 0 and text[i - 1].isalnum() and text[i + 1:i + 2].isalnum():
                i += 1  # a digit separator, 1'000
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            blank(i + 1, min(j, n))
            i = j + 1
        else:
            i += 1
    return "".join(out)


def line_of(offsets, pos):
    """1-based line number of character `pos` (offsets: start of each line)."""
    lo, hi = 0, len(offsets) - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if offsets[mid] <= pos:
            lo = mid
        else:
            hi = mid - 1
    return lo + 1


def matching_brace(code, open_pos):
    """Offset of the `}` closing the `{` at open_pos, or -1."""
    depth = 0
    for k in range(open_pos, len(code)):
        if code[k] == "{":
            depth += 1
        elif code[k] == "}":
            depth -= 1
            if depth == 0:
                return k
    return -1


def strip_template(head):
    """`head` without leading `template <...>` prefixes, and how many characters went."""
    start = 0
    while True:
        m = TEMPLATE_RE.match(head, start)
        if not m:
            return head[start:], start
        depth, k = 0, m.end() - 1
        while k < len(head):
            if head[k] == "<":
                depth += 1
            elif head[k] == ">":
                depth -= 1
                if depth == 0:
                    break
            k += 1
        start = k + 1


def has_top_level_paren(head):
    """Whether `head` has a parameter list (any parentheses)."""
    return "(" in head and ")" in head


def in_ctor_initializers(head):
    """Whether `head` is a constructor signature followed by `: member(...)` initializers."""
    depth = 0
    for k, c in enumerate(head):
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
            if depth == 0:
                rest = head[k + 1:]
                m = re.match(r"\s*(?:noexcept\b\s*)?:(?!:)", rest)
                return bool(m)
    return False


def function_name(head):
    """The name a human would search for: the identifier before the parameter list."""
    flat = " ".join(head.split())
    depth = 0
    for k, c in enumerate(flat):
        if c == "(":
            if depth == 0:
                m = NAME_RE.search(flat[:k + 1])
                if m:
                    return m.group(1)
                # A lambda stored in a variable: `auto name = [..](`.
                m = re.search(r"([A-Za-z_][A-Za-z0-9_]*)\s*=\s*\[[^\]]*\]\s*\($", flat[:k + 1])
                if m:
                    return m.group(1)
            depth += 1
        elif c == ")":
            depth -= 1
    return flat[:60]


def functions(code):
    """(head start, body open, body close, head text) of every function in `code`."""
    found = []

    def scope(begin, end):
        """Reads the declarations between offsets begin and end (a file, namespace or class
        body), recursing into namespaces and classes and recording functions."""
        head_start = begin
        k = begin
        while k < end:
            c = code[k]
            if c in ";}":
                head_start = k + 1
                k += 1
                continue
            if c != "{":
                k += 1
                continue
            head = code[head_start:k]
            m = ACCESS_RE.match(head)
            while m:
                head_start += m.end()
                head = code[head_start:k]
                m = ACCESS_RE.match(head)
            close = matching_brace(code, k)
            if close < 0:
                raise ValueError(f"unbalanced braces after offset {k}")
            if head.count("(") > head.count(")"):
                k = close + 1  # braces inside a parameter list: `Options o = {}`; the head goes on
                continue
            bare, _ = strip_template(head)
            bare = bare.strip()
            if in_ctor_initializers(head) and IDENT_END_RE.search(head):
                k = close + 1  # a member's brace initializer: `: a_{x}`; the head goes on
                continue
            if re.search(r"\bnamespace\b", bare) or re.fullmatch(r'extern\s*""', bare):
                scope(k + 1, close)
            elif CLASS_RE.match(bare):
                scope(k + 1, close)
            elif (has_top_level_paren(bare) and FUNCTION_TAIL_RE.search(bare)
                  and not re.search(r"=\s*$", bare)):
                lead = len(head) - len(head.lstrip())
                found.append((head_start + lead, k, close, head))
            # else: an initializer (`kTable = {...}`, `kName{...}`): not a function
            head_start = close + 1
            k = close + 1
            if k < end and code[k] == ";":
                head_start = k + 1
                k += 1
        return

    scope(0, len(code))
    return found


def comment_above(lines, first_line):
    """The comment lines right above line `first_line` (1-based), top to bottom."""
    out = []
    k = first_line - 2
    in_block = False
    while k >= 0:
        s = lines[k].strip()
        if in_block:
            out.append(s)
            if "/*" in s:
                in_block = False
            k -= 1
            continue
        if s.startswith("//"):
            out.append(s)
        elif s.endswith("*/"):
            out.append(s)
            in_block = "/*" not in s
        else:
            break
        k -= 1
    return list(reversed(out))


def check_file(path, rel):
    """(long undocumented, long documented, all sizes) for one file."""
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    code = blank_code(text)
    lines = text.split("\n")
    offsets = [0]
    for line in lines[:-1]:
        offsets.append(offsets[-1] + len(line) + 1)
    bad, documented, sizes = [], [], []
    for head_start, _open, close, head in functions(code):
        first = line_of(offsets, head_start)
        last = line_of(offsets, close)
        length = last - first + 1
        name = function_name(strip_template(head)[0])
        sizes.append((rel, first, name, length))
        if length <= LIMIT:
            continue
        # The words may wrap onto the next comment line: join the block, drop the comment marks.
        comment = " ".join(re.sub(r"[/*]", " ", " ".join(comment_above(lines, first))).split())
        if MARKER in comment.lower():
            documented.append((rel, first, name, length))
        else:
            bad.append((rel, first, name, length))
    return bad, documented, sizes


def main(argv):
    args = [a for a in argv[1:] if not a.startswith("--")]
    show_all = "--all" in argv[1:]
    if len(args) != 1 or not os.path.isdir(args[0]):
        print("usage: check_function_length.py REPO_ROOT [--all]", file=sys.stderr)
        return 2
    root = os.path.abspath(args[0])
    bad, documented, sizes = [], [], []
    files = 0
    for full, rel in source_files(root, SCANNED_ROOTS):
        files += 1
        try:
            b, d, s = check_file(full, rel)
        except ValueError as e:
            print(f"{rel}: cannot read its functions: {e}", file=sys.stderr)
            return 2
        bad += b
        documented += d
        sizes += s
    for rel, line, name, length in documented:
        print(f"note: {rel}:{line}: {name} is {length} lines, long as its comment says",
              file=sys.stderr)
    if show_all:
        for rel, line, name, length in sorted(sizes, key=lambda t: -t[3]):
            if length > LIMIT // 2:
                print(f"size: {rel}:{line}: {name} {length}", file=sys.stderr)
    for rel, line, name, length in bad:
        print(f"{rel}:{line}: {name} is {length} lines (limit {LIMIT}); split it by job or "
              f'say "{MARKER} ..." in the comment above it')
    if bad:
        print(f"{len(bad)} long function(s) without a reason in {files} files "
              f"({len(sizes)} functions)", file=sys.stderr)
        return 1
    print(f"no function over {LIMIT} lines without a reason in {files} files "
          f"({len(sizes)} functions, {len(documented)} long with a reason)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
