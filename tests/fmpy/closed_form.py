"""The closed-form references of the models, evaluated here as `runner compare`, `runner handbook`
and the Rust tests evaluate them (runner-engine's `metrics::Formula` and `references::References`),
so each closed form is written once: experiment.toml's `[compare.reference]` (formulas of t and
the parameters) and references.toml (named formulas, where a name that is another entry of the
file stands for that entry's value; `include = [...]` takes the entries of other files, relative
to it). The grammar is the Formula's: numbers, names, `+ - * /`, `^` (right-associative, binding
tighter than unary minus: -x^2 = -(x^2), 2^-1 = 0.5), parentheses, the constant pi, the
functions of one argument exp log sqrt sin cos tan asin acos atan abs ellipk (the complete
elliptic integral of the first kind of the parameter m = k^2, scipy's convention; scipy
evaluates it here, an arithmetic-geometric mean in Rust) and of two, atan2(y, x) and
hypot(x, y); names take numpy arrays or numbers."""

import pathlib
import re
import tomllib

import numpy as np
from scipy.special import ellipk

from conftest import ROOT

# The table of runner-engine's metrics::FUNCTIONS: name -> (number of arguments, numpy's function).
FUNCTIONS = {"exp": (1, np.exp), "log": (1, np.log), "sqrt": (1, np.sqrt), "sin": (1, np.sin), "cos": (1, np.cos),
             "tan": (1, np.tan), "asin": (1, np.arcsin), "acos": (1, np.arccos), "atan": (1, np.arctan),
             "atan2": (2, np.arctan2), "hypot": (2, np.hypot), "abs": (1, np.abs), "ellipk": (1, ellipk)}
# metrics::CONSTANTS: a name a formula cannot take from its caller.
CONSTANTS = {"pi": np.pi}
# The key of a references.toml that lists the files whose entries it takes too.
INCLUDE = "include"
TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)|([A-Za-z_]\w*)|(\S))")


def _tokens(text):
    pos, out = 0, []
    while pos < len(text):
        m = TOKEN.match(text, pos)
        if not m or m.end() == pos:
            break
        if m.group(0).strip():
            out.append(("num", float(m.group(1))) if m.group(1) else ("name", m.group(2)) if m.group(2) else ("op", m.group(3)))
        pos = m.end()
    return out


class Formula:
    """A parsed formula; `Formula(text)(t=..., k=...)` evaluates it."""

    def __init__(self, text):
        self.text, self._tokens, self._pos = text, _tokens(text), 0
        self.names = []
        self._tree = self._expression()
        if self._pos != len(self._tokens):
            raise ValueError(f"unexpected {self._tokens[self._pos]} in {text!r}")

    def _peek(self, op):
        return self._pos < len(self._tokens) and self._tokens[self._pos] == ("op", op)

    def _take(self, op):
        if not self._peek(op):
            raise ValueError(f"expected {op!r} in {self.text!r}")
        self._pos += 1

    def _expression(self):
        left = self._term()
        while self._peek("+") or self._peek("-"):
            op = self._tokens[self._pos][1]
            self._pos += 1
            left = (op, left, self._term())
        return left

    def _term(self):
        left = self._unary()
        while self._peek("*") or self._peek("/"):
            op = self._tokens[self._pos][1]
            self._pos += 1
            left = (op, left, self._unary())
        return left

    def _unary(self):
        if self._peek("-"):
            self._pos += 1
            return ("neg", self._unary())
        base = self._atom()
        if self._peek("^"):
            self._pos += 1
            return ("^", base, self._unary())
        return base

    def _atom(self):
        if self._peek("("):
            self._pos += 1
            e = self._expression()
            self._take(")")
            return e
        if self._pos >= len(self._tokens):
            raise ValueError(f"unexpected end of {self.text!r}")
        kind, value = self._tokens[self._pos]
        self._pos += 1
        if kind == "num":
            return ("num", value)
        if kind == "name" and self._peek("("):
            if value not in FUNCTIONS:
                raise ValueError(f"{value!r} is not a function in {self.text!r}; use one of {', '.join(FUNCTIONS)}")
            self._pos += 1
            arguments = [self._expression()]
            while self._peek(","):
                self._pos += 1
                arguments.append(self._expression())
            self._take(")")
            arity = FUNCTIONS[value][0]
            if len(arguments) != arity:
                raise ValueError(f"{value!r} in {self.text!r} takes {arity} argument{'s' * (arity != 1)}, "
                                 f"given {len(arguments)}")
            return ("call", value, arguments)
        if kind == "name" and value in CONSTANTS:
            return ("num", CONSTANTS[value])
        if kind == "name":
            if value not in self.names:
                self.names.append(value)
            return ("name", value)
        raise ValueError(f"unexpected {value!r} in {self.text!r}")

    def __call__(self, **values):
        missing = [n for n in self.names if n not in values]
        if missing:
            raise KeyError(f"{self.text!r} reads {missing}")
        return self._eval(self._tree, values)

    def _eval(self, node, values):
        kind = node[0]
        if kind == "num":
            return node[1]
        if kind == "name":
            return values[node[1]]
        if kind == "neg":
            return -self._eval(node[1], values)
        if kind == "call":
            return FUNCTIONS[node[1]][1](*(self._eval(a, values) for a in node[2]))
        a, b = self._eval(node[1], values), self._eval(node[2], values)
        return {"+": lambda: a + b, "-": lambda: a - b, "*": lambda: a * b, "/": lambda: a / b,
                "^": lambda: np.power(a, b)}[kind]()


def reference(model, output):
    """The closed form of `output` in models/<model>/experiment.toml."""
    with open(ROOT / "models" / model / "experiment.toml", "rb") as f:
        return Formula(tomllib.load(f)["compare"]["reference"][output])


class References:
    """A model's references.toml: `references(model)["name"](t=..., K=...)` evaluates entry
    `name`, the entries it uses first (as runner-engine's `References::value` does);
    `.matrix("name", ...)` evaluates a matrix entry (rows of formulas) to a numpy array."""

    def __init__(self, table):
        if INCLUDE in table:
            raise ValueError(f"{INCLUDE!r} names files relative to a references.toml: read it with load(path)")
        for name in CONSTANTS:
            if name in table:
                raise ValueError(f"reference {name}: {name!r} is a constant of the formulas, not a name for an entry")
        self.formulas = {name: Formula(text) for name, text in table.items() if isinstance(text, str)}
        self.matrices = {name: [[Formula(cell) for cell in row] for row in rows]
                         for name, rows in table.items() if isinstance(rows, list)}
        for name, rows in self.matrices.items():
            if any(len(row) != len(rows[0]) for row in rows):
                raise ValueError(f"matrix reference {name}: rows of different lengths")
        for name in self.formulas:
            self._check_acyclic(name, [])

    def _check_acyclic(self, name, path):
        if name in path:
            raise ValueError(f"references use each other in a cycle: {' -> '.join(path + [name])}")
        for used in self.formulas[name].names if name in self.formulas else []:
            self._check_acyclic(used, path + [name])

    def value(self, name, values):
        return self._evaluate(self.formulas[name], values)

    def _evaluate(self, formula, values):
        args = {used: self.value(used, values) if used in self.formulas else values[used] for used in formula.names}
        return formula(**args)

    def matrix(self, name, **values):
        return np.array([[float(self._evaluate(cell, values)) for cell in row] for row in self.matrices[name]])

    def __getitem__(self, name):
        if name not in self.formulas:
            raise KeyError(f"there is no reference {name!r}")
        return lambda **values: self.value(name, values)


def _read_with_includes(path, stack, entries, origin):
    """The entries of `path` and of the files it includes (relative to it, transitively) into
    `entries`, as runner-engine's `References::from_file` reads them: a name given twice and a
    cycle of includes are refused naming the files."""
    path = pathlib.Path(path)
    if path in stack:
        raise ValueError(f"references include each other in a cycle: {' -> '.join(map(str, stack + [path]))}")
    with open(path, "rb") as f:
        table = tomllib.load(f)
    includes = table.pop(INCLUDE, [])
    if not isinstance(includes, list) or not all(isinstance(p, str) for p in includes):
        raise ValueError(f"{path}: {INCLUDE!r} must be an array of file paths (relative to this file)")
    for name, value in table.items():
        if name in entries:
            raise ValueError(f"reference {name} is given twice: in {origin[name]} and in {path}")
        entries[name], origin[name] = value, path
    for included in includes:
        _read_with_includes(path.parent / included, stack + [path], entries, origin)


def load(path):
    """The references.toml at `path` with the files it includes."""
    entries = {}
    _read_with_includes(path, [], entries, {})
    return References(entries)


def references(model):
    """The named closed forms of models/<model>/references.toml (and the files it includes)."""
    return load(ROOT / "models" / model / "references.toml")
