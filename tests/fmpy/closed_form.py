"""The closed-form references of the models' experiment.toml (`[compare.reference]`), evaluated
here as `runner compare` and the Rust tests evaluate them (runner-engine's `metrics::Formula`),
so each closed form is written once. The grammar is the Formula's: numbers, names, `+ - * /`,
`^` (right-associative, binding tighter than unary minus: -x^2 = -(x^2), 2^-1 = 0.5),
parentheses and the one-argument functions exp log sqrt sin cos tan atan abs; names take numpy
arrays or numbers."""

import re
import tomllib

import numpy as np

from conftest import ROOT

FUNCTIONS = {"exp": np.exp, "log": np.log, "sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "tan": np.tan,
             "atan": np.arctan, "abs": np.abs}
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
