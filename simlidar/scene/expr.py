"""Arithmetic expressions in scene recipes, evaluated on whole batches with numpy.

A recipe value may be a number or a string such as ``"-half_width_m - 0.3"`` or
``"first_m + i * spacing_m"``: numbers, parameter names, ``i`` (the index of a repeated
primitive), ``+ - * / **``, parentheses and the functions in :data:`FUNCTIONS`. Nothing else is
accepted, so a recipe can never run code. Names starting with ``_`` are the language's own (its
numbers are bound to ``_c0``, ``_c1``, ...): no expression reads one and no parameter takes one,
nor ``i``, a function's name or a Python keyword (:func:`is_parameter_name`). An expression is at
most :data:`MAX_EXPRESSION_CHARS` characters long and nests at most :data:`MAX_EXPRESSION_DEPTH`
deep, both checked before Python's parser sees it (which would otherwise recurse, or allocate,
in proportion to the text).
"""

import ast
import copy
import keyword
import re
from collections.abc import Callable, Mapping
from types import CodeType
from typing import NamedTuple

import numpy as np

from simlidar.errors import shown

FUNCTIONS: dict[str, Callable] = {
    "sin": lambda x: np.sin(np.deg2rad(x)),  # degrees, like every angle in a recipe
    "cos": lambda x: np.cos(np.deg2rad(x)),
    "sqrt": np.sqrt,
    "abs": np.abs,
    "min": np.minimum,
    "max": np.maximum,
}
_ARITY = {"sin": 1, "cos": 1, "sqrt": 1, "abs": 1, "min": 2, "max": 2}
# The names a recipe's parameters cannot take: a parameter named like a function or ``i`` would
# hide it, and a keyword could never be read by an expression.
RESERVED = frozenset({"i", *FUNCTIONS, *keyword.kwlist})
# ASCII only, and never a leading "_": "_c0", "__builtins__" are the evaluation's own names, and
# Python folds other letters into ASCII ones (NFKC: an expression's "ｉ" reads "i"), so a name
# that is not plain ASCII would not be the name the expression reads.
_PARAMETER_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
PARAMETER_NAME_RULE = (
    "a letter, then letters, digits or '_' (not i, a function's name or a Python keyword)"
)
_BINARY = {
    ast.Add: np.add,
    ast.Sub: np.subtract,
    ast.Mult: np.multiply,
    ast.Div: np.divide,
    ast.Pow: np.power,
}


# The longest shipped expression has 49 characters and nests 2 deep. Within these limits the
# syntax tree stays shallow enough for the parser, copy.deepcopy and compile.
MAX_EXPRESSION_CHARS = 256
MAX_EXPRESSION_DEPTH = 32
_OPERAND_EXPECTED = set("([{,+-*/")  # after these, a + or - is a sign, not an operator


class ExpressionError(ValueError):
    """An expression uses something outside the recipe language."""


def _show(text: str, limit: int = 60) -> str:
    """``text`` quoted for an error message, cut to ``limit`` characters."""
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}... ({len(text)} characters)"


def is_parameter_name(name: str) -> bool:
    """Whether a recipe may name a parameter ``name`` (:data:`PARAMETER_NAME_RULE`)."""
    return _PARAMETER_NAME.fullmatch(name) is not None and name not in RESERVED


def nesting(text: str) -> int:
    """How deeply ``text`` nests, counted on the characters without parsing: the brackets open
    at once plus the unary signs still waiting for their operand (``-(-(1))`` nests 4 deep)."""
    signs = [0]  # unary signs waiting for their operand, per open bracket
    waiting = deepest = 0
    prev = "("  # the start of the text expects an operand, like an open bracket
    for ch in text:
        if ch.isspace():
            continue
        if ch in "([{":
            signs.append(0)
        elif ch in ")]}":
            if len(signs) > 1:
                waiting -= signs.pop()
        elif ch in "+-" and prev in _OPERAND_EXPECTED:
            signs[-1] += 1
            waiting += 1
        elif ch in "+-*/,":  # an operator or the next argument: the signs before are done
            waiting -= signs[-1]
            signs[-1] = 0
        deepest = max(deepest, len(signs) - 1 + waiting)
        prev = ch
    return deepest


def parse(text: str) -> ast.expr:
    """Parse ``text`` and check it uses only the recipe language; return its syntax tree."""
    if len(text) > MAX_EXPRESSION_CHARS:
        raise ExpressionError(
            f"expected an expression of at most {MAX_EXPRESSION_CHARS} characters, "
            f"got {_show(text)}"
        )
    depth = nesting(text)
    if depth > MAX_EXPRESSION_DEPTH:
        raise ExpressionError(
            f"expected an expression nested at most {MAX_EXPRESSION_DEPTH} deep (brackets and "
            f"unary signs), got {depth} deep in {_show(text)}"
        )
    try:
        tree = ast.parse(text, mode="eval").body
    except SyntaxError as exc:
        raise ExpressionError(f"cannot parse {text!r}: {exc.msg}") from None
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
                raise ExpressionError(
                    f"{text!r}: only the functions {sorted(FUNCTIONS)} may be called"
                )
            if node.keywords:
                raise ExpressionError(f"{text!r}: keyword arguments are not allowed")
            if len(node.args) != _ARITY[node.func.id]:
                raise ExpressionError(
                    f"{text!r}: {node.func.id}() takes {_ARITY[node.func.id]} argument(s)"
                )
        elif not isinstance(
            node,
            ast.BinOp
            | ast.UnaryOp
            | ast.Name
            | ast.Constant
            | ast.Load
            | ast.operator
            | ast.unaryop,
        ):
            raise ExpressionError(f"{text!r}: {type(node).__name__} is not allowed")
        if isinstance(node, ast.Constant) and (
            isinstance(node.value, bool) or not isinstance(node.value, int | float)
        ):
            raise ExpressionError(f"{text!r}: only numbers may appear as constants")
        if isinstance(node, ast.BinOp) and type(node.op) not in _BINARY:
            raise ExpressionError(f"{text!r}: operator {type(node.op).__name__} is not allowed")
        if isinstance(node, ast.UnaryOp) and not isinstance(node.op, ast.USub | ast.UAdd):
            raise ExpressionError(f"{text!r}: operator {type(node.op).__name__} is not allowed")
    # compile_tree binds the numbers to _c0, _c1, ... and the functions by name: read as a
    # variable, such a name would give the binding, whatever the caller meant by it
    own = sorted(n for n in names(tree) if n.startswith("_") or n in FUNCTIONS)
    if own:
        raise ExpressionError(f"{text!r}: {own[0]!r} is the language's own name, not a parameter")
    return tree


def names(tree: ast.expr) -> set[str]:
    """The variable names an expression reads (function names excluded)."""
    called = {id(n.func) for n in ast.walk(tree) if isinstance(n, ast.Call)}
    return {n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and id(n) not in called}


class _NumpyConstants(ast.NodeTransformer):
    """Turn number literals into names bound to numpy float64 values, so that arithmetic on
    constants follows numpy (inf, nan) instead of raising or, for ``9 ** 9 ** 9``, hanging."""

    def __init__(self) -> None:
        self.values: dict[str, np.float64] = {}

    def visit_Constant(self, node: ast.Constant) -> ast.Name:
        name = f"_c{len(self.values)}"
        self.values[name] = np.float64(node.value)
        return ast.copy_location(ast.Name(id=name, ctx=ast.Load()), node)


class Compiled(NamedTuple):
    """A compiled expression (:func:`compile_tree`)."""

    code: CodeType  # the bytecode
    namespace: dict  # what it reads besides the variables: FUNCTIONS, its numbers
    # its value, where it reads no variable (numbers and functions only), else None: worked
    # out once, as :func:`evaluate` would each time
    constant: np.float64 | None


def compile_tree(tree: ast.expr) -> Compiled:
    """Compile a tree checked by :func:`parse` (its numbers as numpy floats)."""
    constants = _NumpyConstants()
    body = ast.fix_missing_locations(constants.visit(copy.deepcopy(tree)))
    code = compile(ast.Expression(body=body), "<recipe expression>", "eval")
    namespace = {"__builtins__": {}, **FUNCTIONS, **constants.values}
    value = None
    if not names(tree):
        try:
            with np.errstate(all="ignore"):  # inf and nan are caught by the caller's checks
                value = eval(code, namespace, {})  # checked AST, no builtins
        except (ArithmeticError, TypeError, ValueError):
            value = None  # raised again by evaluate, where the caller says which key
    return Compiled(code, namespace, value)


def evaluate(compiled: Compiled, env: Mapping[str, np.ndarray]) -> np.ndarray:
    """Evaluate a compiled expression; ``env`` maps names to broadcastable float arrays.

    Only what :func:`parse` allowed can appear (numbers, names, arithmetic, FUNCTIONS). A
    variable in ``env`` named like one of the expression's own names (a function, ``_c0``, ...)
    is refused: as a local it would replace that name wherever the expression reads it.
    """
    if compiled.constant is not None:
        return compiled.constant
    if not compiled.namespace.keys().isdisjoint(env):
        taken = sorted(compiled.namespace.keys() & env.keys())
        raise ExpressionError(
            f"expected variables named apart from the expression's own names, got {shown(taken)}"
        )
    with np.errstate(all="ignore"):  # inf and nan are caught by the caller's checks
        return eval(compiled.code, compiled.namespace, dict(env))  # checked AST, no builtins
