"""The closed-form references of the models, evaluated here as `runner compare`, `runner handbook`
and the Rust tests evaluate them (runner-engine's `metrics::Formula` and `references::References`),
so each closed form is written once: experiment.toml's `[compare.reference]` (formulas of t and
the parameters) and references.toml (named formulas, where a name that is another entry of the
file stands for that entry's value). The grammar is the Formula's: numbers, names, `+ - * /`,
`^` (right-associative, binding tighter than unary minus: -x^2 = -(x^2), 2^-1 = 0.5),
parentheses and the one-argument functions exp log sqrt sin cos tan atan abs ellipk (the
complete elliptic integral of the first kind of the parameter m = k^2, scipy's convention;
scipy evaluates it here, an arithmetic-geometric mean in Rust); names take numpy arrays or
numbers."""

import re
import tomllib

import numpy as np
from scipy.special import ellipk

from conftest import ROOT

FUNCTIONS = {"exp": np.exp, "log": np.log, "sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "tan": np.tan,
             "atan": np.arctan, "abs": np.abs, "ellipk": ellipk}
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
                raise ValueError(f"{value!r} is not a function in {self.text!r}")
            self._pos += 1
            argument = self._expression()
            self._take(")")
            return ("call", value, argument)
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
            return FUNCTIONS[node[1]](self._eval(node[2], values))
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


def references(model):
    """The named closed forms of models/<model>/references.toml."""
    with open(ROOT / "models" / model / "references.toml", "rb") as f:
        return References(tomllib.load(f))
