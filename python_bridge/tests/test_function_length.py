"""The engine's functions, read from the sources of native/src (nothing is compiled): no function
definition is longer than MAX_LINES lines, counted from the line of its name to the line of its
closing brace. Lambdas and local classes count toward the function that holds them; class bodies
and namespaces are not functions, but the member functions defined in them are.

The sources are scanned with a small brace matcher: comments, string and character literals and
preprocessor lines are blanked first, then each `{` at namespace or class scope is classified by
the text before it (a namespace, class, struct, union or enum; a function's signature; else an
initializer).

Run as a script, it prints the figures: the number of functions, and the longest ones with their
lengths."""
import os
import re
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "native")
SRC = os.path.join(ROOT, "src")
MAX_LINES = 150
# Functions allowed over MAX_LINES, as (file under native/src, name): none. An entry must name a
# function that exists (test_allowed_functions_exist).
ALLOWED = set()

RAW_PREFIX = re.compile(r"(?<![\w])(?:u8|[uUL])?R$")  # before the '"' of a raw string literal
RAW_OPEN = re.compile(r'"([^ ()\\\t\n]{0,16})\(')
IDENT = re.compile(r"[A-Za-z_]\w*")
SCOPE_KEYWORD = re.compile(r"\b(namespace|class|struct|union|enum|extern)\b")
# What may follow a function's parameter list before its body (or before its constructor
# initializer list, which starts with a single ':').
QUALIFIERS = re.compile(r"(\s+|const\b|volatile\b|noexcept\b|override\b|final\b|mutable\b|&&|&|->[^:{]*)*")
# A function's name, qualified or not, just before its parameter list.
NAME = re.compile(r"((?:~?[A-Za-z_]\w*(?:\s*<[^()]*>)?\s*::\s*)*~?(?:operator\s+)?([A-Za-z_]\w*))\s*$")
OPERATOR = re.compile(r"\b(operator)\s*(\(\s*\)|\[\s*\]|[^\w\s(]+)")
NOT_NAMES = {"if", "for", "while", "switch", "catch", "return", "sizeof", "decltype", "alignas", "noexcept",
             "static_assert", "__attribute__", "__declspec", "operator"}


def sources():
    """Every .h and .cpp under native/src, as a path relative to it."""
    out = []
    for folder, _, files in os.walk(SRC):
        out += [os.path.relpath(os.path.join(folder, f), SRC) for f in files if f.endswith((".h", ".cpp"))]
    return sorted(p.replace(os.sep, "/") for p in out)


def blank(text):
    """The text with comments, string and character literals and preprocessor lines replaced by
    spaces, and of each #if group only the first branch kept (the second after #if 0), as ctags
    reads it; newlines are kept, so offsets and line numbers stay those of the source."""
    out = list(text)
    n = len(text)
    directives = []  # (offset, end, directive) of each preprocessor line
    i = 0
    line_start = True  # only white space since the last newline

    def clear(a, b):
        for k in range(a, b):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = text[i]
        j = i + 1
        if c == "\n":
            line_start = True
        elif c in " \t\r\f\v":
            pass
        elif c == "#" and line_start:
            while j < n and text[j] != "\n":
                j += 2 if text[j] == "\\" and j + 1 < n else 1  # a backslash continues the line
            directives.append((i, j, text[i + 1:j].split("//")[0].split()))
            clear(i, j)
        elif text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            clear(i, j)
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            clear(i, j)
        elif c == '"' and RAW_PREFIX.search(text, max(0, i - 3), i):
            m = RAW_OPEN.match(text, i)
            close = text.find(")" + m.group(1) + '"', m.end()) if m else -1
            j = n if close < 0 else close + len(m.group(1)) + 2
            clear(i, j)
        elif c == '"' or (c == "'" and not _digit_separator(text, i)):
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            clear(i + 1, j - 1)  # keep the quotes: a literal stays a token
        if c not in " \t\r\f\v\n":
            line_start = False
        i = j

    # Conditional groups: [branch kept, branch now] per open #if; text outside the kept branches
    # (of every group open around it) is cleared.
    groups = []
    skip_from = None
    for begin, finish, words in directives:
        word = words[0] if words else ""
        skipping = any(kept != now for kept, now in groups)
        if word in ("if", "ifdef", "ifndef"):
            groups.append([1 if words[1:] == ["0"] else 0, 0])
        elif word in ("elif", "else") and groups:
            groups[-1][1] += 1
        elif word == "endif" and groups:
            groups.pop()
        now_skipping = any(kept != now for kept, now in groups)
        if now_skipping and not skipping:
            skip_from = finish
        elif skipping and not now_skipping:
            clear(skip_from, begin)
    if skip_from is not None and any(kept != now for kept, now in groups):
        clear(skip_from, n)
    return "".join(out)


def _digit_separator(text, i):
    """Whether the ' at i separates digits of a number (1'000), not a character literal."""
    j = i
    while j > 0 and (text[j - 1].isalnum() or text[j - 1] in "_.'"):
        j -= 1
    return j < i and text[j].isdigit()


def matching(text, i, open_, close):
    """The index of the bracket closing the one at i (blanked text), or len(text)."""
    depth = 0
    for j in range(i, len(text)):
        if text[j] == open_:
            depth += 1
        elif text[j] == close:
            depth -= 1
            if depth == 0:
                return j
    return len(text)


def _without_templates(head):
    """The head with `template <...>` prefixes, attributes and alignas(...) blanked (same length)."""
    head = re.sub(r"\[\[.*?\]\]", lambda m: " " * len(m.group()), head, flags=re.S)
    for m in list(re.finditer(r"\b(alignas|__attribute__|__declspec)\s*\(", head)):
        end = matching(head, m.end() - 1, "(", ")")
        head = head[:m.start()] + " " * (end + 1 - m.start()) + head[end + 1:]
    while True:
        m = re.search(r"\btemplate\s*<", head)
        if not m:
            return head
        end = matching(head, m.end() - 1, "<", ">")
        head = head[:m.start()] + " " * (end + 1 - m.start()) + head[end + 1:]


def _parameter_list(head):
    """(index of the name's start, of the parameter list's '(' and of its ')') of a function's
    signature, or None: the first '(' outside template arguments that follows a name. Operator
    names are read as names (operator(), operator==, operator bool)."""
    head = OPERATOR.sub(lambda m: m.group(1) + "_" * (len(m.group()) - len(m.group(1))), head)
    angle = 0
    i = 0
    while i < len(head):
        c = head[i]
        if c == "<":
            angle += 1
        elif c == ">" and head[i - 1] != "-":
            angle = max(0, angle - 1)
        elif c == "(" and angle == 0:
            m = NAME.search(head, 0, i)
            close = matching(head, i, "(", ")")
            if m is None:
                return None
            if m.group(2) not in NOT_NAMES:
                return m.start(1), i, close
            if m.group(2) not in ("decltype", "alignas", "noexcept"):
                return None
            i = close
        elif c in ";=" and angle == 0:
            return None
        i += 1
    return None


def classify(head):
    """What a '{' at namespace or class scope opens, from the text since the last ';', '{' or '}':
    ("scope", name), ("skip", None) for an enum's body or an initializer, ("function", (name, offset
    of the name in head)), or ("init list", None) for a brace initializer in a constructor's
    initializer list."""
    clean = _without_templates(head)
    clean = re.sub(r"\b(public|private|protected)\s*:(?!:)", lambda m: " " * len(m.group()), clean)
    found = _parameter_list(clean)
    if found is None:
        m = SCOPE_KEYWORD.search(clean)
        if m and m.group(1) == "enum":
            return "skip", None
        if m:
            name = IDENT.findall(re.sub(r"\bfinal\b", "", clean[m.end():].split(":")[0]))
            return "scope", (name[-1] if name and m.group(1) in ("class", "struct", "union") else None)
        return "skip", None
    start, _, close = found
    rest = clean[close + 1:]
    q = QUALIFIERS.match(rest)
    tail = rest[q.end():]
    if tail.strip() == "":
        name = re.sub(r"\s+", "", clean[start:found[1]])
        return "function", (name, start)
    if tail.lstrip().startswith(":") and not tail.lstrip().startswith("::"):
        # A constructor's initializer list: a brace after a member's name initializes it.
        if re.search(r"[\w>]\s*$", tail):
            return "init list", None
        name = re.sub(r"\s+", "", clean[start:found[1]])
        return "function", (name, start)
    return "skip", None


def functions_in(source):
    """(name, first line, last line) of every function defined in C++ source text. A member
    function defined in its class is named Class::name, as one defined outside it."""
    text = blank(source)
    out = []

    def scan(begin, end, classes):
        head = begin
        i = begin
        while i < end:
            c = text[i]
            if c in ";}":
                head = i + 1
            elif c == "(":
                i = matching(text, i, "(", ")")  # a brace in a default argument is not a body
            elif c == "{":
                close = matching(text, i, "{", "}")
                kind, what = classify(text[head:i])
                if kind == "function":
                    name, offset = what
                    qualified = "::".join(classes + [name]) if "::" not in name else name
                    out.append((qualified, text.count("\n", 0, head + offset) + 1, text.count("\n", 0, close) + 1))
                    head = close + 1
                elif kind == "scope":
                    scan(i + 1, close, classes + ([what] if what else []))
                    head = close + 1
                elif kind == "skip" and not re.match(r"\s*[;,)\w]", text[close + 1:close + 200]):
                    head = close + 1  # a body not understood: the next head starts after it
                # else an initializer or an enum's body: the head goes on to the ';'
                i = close
            i += 1

    scan(0, len(text), [])
    return out


def functions(path):
    """functions_in for a source under native/src."""
    return functions_in(open(os.path.join(SRC, path), encoding="utf-8").read())


def all_functions():
    """(length in lines, file, name, first line) of every function under native/src, longest first."""
    found = []
    for path in sources():
        for name, first, last in functions(path):
            found.append((last - first + 1, path, name, first))
    return sorted(found, key=lambda f: (-f[0], f[1], f[3]))


FUNCTIONS = all_functions()


def test_the_scanner_finds_functions():
    names = {(f[1], f[2]) for f in FUNCTIONS}
    assert len(FUNCTIONS) > 1000
    assert ("csg/csg_lightmap.cpp", "CsgLightmap::CsgLightmap") in names
    assert ("lightmap/stitch.cpp", "stitch_images") in names
    assert ("lsystem/graph/graph_trace.cpp", "Graph::first_hit") in names


TRICKY = r"""
#define BODY(x) { if (x) { return; } }
namespace a::b {
// a comment with a brace {
/* and a block comment } */
const char* kText = "a string with a { brace";
const char* kRaw = R"x(a raw string with } braces { )x";
constexpr char kOpen = '{';
constexpr int kMillion = 1'000'000;
constexpr double kTable[3] = {1, 2, 3};
enum class Kind : int { A, B };
template <class T, int N = 3>
struct Box final : public Base<T> {
  int n{0};
  std::vector<int> v = {1, 2};
  Box() : n{1}, v(2) {
    auto f = [&](int k) {
      return k + n;
    };
  }
  bool operator()(int k) const { return k == '}'; }
  auto get() const noexcept -> T { return T{}; }
};
void free_function(int x = int{3},
                   const char* s = "}") {
  struct Local {
    void method() {}
  };
#if defined(X)
  if (x) {
#else
  if (!x) {
#endif
  }
}
auto lambda = [](int k) { return k; };
#if 0
void old_function() {
}
#else
void new_function() {
  return;
}
#endif
}  // namespace a::b
"""


def test_the_scanner_on_tricky_source():
    assert functions_in(TRICKY) == [
        ("Box::Box", 16, 20),
        ("Box::operator()", 21, 21),
        ("Box::get", 22, 22),
        ("free_function", 24, 35),
        ("new_function", 41, 43),
    ]


def test_allowed_functions_exist():
    names = {(f[1], f[2]) for f in FUNCTIONS}
    assert sorted(ALLOWED - names) == [], "allowed functions that no longer exist: remove them from ALLOWED"


def test_no_function_is_longer_than_150_lines():
    over = ["%s:%d %s: %d lines" % (path, first, name, n) for n, path, name, first in FUNCTIONS
            if n > MAX_LINES and (path, name) not in ALLOWED]
    assert over == [], "functions longer than %d lines: %s" % (MAX_LINES, "; ".join(over))


def main(count=10):
    print("functions: %d, over %d lines: %d (%d allowed)" % (
        len(FUNCTIONS), MAX_LINES, sum(f[0] > MAX_LINES for f in FUNCTIONS),
        sum(f[0] > MAX_LINES and (f[1], f[2]) in ALLOWED for f in FUNCTIONS)))
    for n, path, name, first in FUNCTIONS[:count]:
        print("%5d  %s:%d  %s%s" % (n, path, first, name, "  (allowed)" if (path, name) in ALLOWED else ""))


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 10))
