"""A small, safe arithmetic evaluator for the model files in ``models/``.

Measured geometry is written as it was measured and scaled, e.g.
``"(1.9375+2.84375)/4*1.27576*41/12/3.9"``, and the gear-ratio scaling rules of Appendix B
as conditional expressions, e.g. ``"x*G/g if g < G else x"``. Only numbers, names from the
given namespace, + - * / **, comparisons, ``a if c else b`` and a few math functions are
allowed; anything else is refused with an error naming the file and key.
"""
from __future__ import annotations

import ast
import math
import operator

from fleetrun.errors import InputError

_FUNCTIONS = {
    "sqrt": math.sqrt, "acos": math.acos, "asin": math.asin, "atan": math.atan,
    "cos": math.cos, "sin": math.sin, "tan": math.tan, "log10": math.log10, "abs": abs,
    "radians": math.radians, "min": min, "max": max,
}
_CONSTANTS = {"pi": math.pi}
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_COMPARE = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
            ast.GtE: operator.ge, ast.Eq: operator.eq, ast.NotEq: operator.ne}


def evaluate(expression, namespace: dict, *, where: str = "") -> float:
    """Evaluate a number or an expression string against ``namespace``.

    Parameters
    ----------
    expression : int, float or str, a number or an arithmetic expression
    namespace : dict, the names the expression may use
    where : str, the file and key to name in an error

    Returns
    -------
    float, the value (in the units of the names it combines).
    """
    if isinstance(expression, bool):
        raise InputError(f"{where}: expected a number or expression, got {expression!r}")
    if isinstance(expression, (int, float)):
        return float(expression)
    try:
        tree = ast.parse(str(expression), mode="eval")
    except SyntaxError:
        raise InputError(f"{where}: '{expression}' is not an arithmetic expression") from None
    return float(_eval(tree.body, namespace, expression, where))


def _eval(node, ns, text, where):
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return node.value
    if isinstance(node, ast.Name):
        if node.id in ns:
            return ns[node.id]
        if node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        known = sorted(set(ns) | set(_CONSTANTS))
        raise InputError(f"{where}: unknown name '{node.id}' in '{text}'; known: {', '.join(known)}")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return _BINARY[type(node.op)](_eval(node.left, ns, text, where), _eval(node.right, ns, text, where))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _eval(node.operand, ns, text, where)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _COMPARE:
        return _COMPARE[type(node.ops[0])](_eval(node.left, ns, text, where),
                                           _eval(node.comparators[0], ns, text, where))
    if isinstance(node, ast.IfExp):
        test = _eval(node.test, ns, text, where)
        return _eval(node.body if test else node.orelse, ns, text, where)
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS
            and not node.keywords):
        return _FUNCTIONS[node.func.id](*[_eval(a, ns, text, where) for a in node.args])
    raise InputError(f"{where}: '{text}' uses something other than arithmetic "
                     f"({type(node).__name__}); allowed: numbers, names, + - * / **, "
                     f"comparisons, 'a if c else b', {', '.join(sorted(_FUNCTIONS))}")
