"""Generated straight-line functions lowered to LLVM IR directly, past numba's front end.

numba types and lowers a function one statement at a time, in Python, and a robot's
generated dynamics are thousands of statements (UR5's closed-loop Jacobian 7,585,
Panda's ~21,000): their compilation was most of a robot's first use, and not LLVM's part
of it (the same at O0). The generated functions use a small part of Python, which
:func:`lowered` translates to LLVM IR inside one numba intrinsic: numba's IR then holds
one call, and LLVM gets the instructions numba would have emitted (IEEE operations without
fast-math flags, so no contraction into FMA; LLVM's ``sin``/``cos``/``fabs`` intrinsics and
libm's ``sqrt`` and ``tanh``, as numba's math does), so the results are the same bits
(``tests/test_straight.py`` compares both on random inputs). Compile times before and
after: ``docs/benchmarks.md``.

The part of Python, checked by :func:`supported` (pure, numba-free: the module writer asks
it before choosing): a function of float64 arrays (1-D or 2-D) and integer loop counts
whose body is assignments to names or to array elements, ``+=`` and the like,
``if``/``else`` blocks, conditional expressions, ``+ - * / &``, unary minus, one
comparison at a time, ``math.nan``/``math.inf``, and calls of ``abs``, ``int``,
``float``, ``sin``, ``cos``, ``sqrt``, ``tanh``, ``max`` and ``min``; or one counted loop
``for j in range(N)`` (N a constant or a count) around such a body, its array indices
``j + constant`` (the lanes' and the RNEA's blocks). Elsewhere indices are constants.
Names hold float64 or int64 values (an int meets a float as Python's does: converted),
each assigned before it is read on every path.

Units: none (code).
"""

from __future__ import annotations

import ast
import re
from typing import Any

__all__ = ["lowered", "lowered_part", "stub", "supported"]  # and VERSION (lazy)

_CALLS = frozenset({"abs", "int", "float", "sin", "cos", "sqrt", "tanh"})
_BINOPS = (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.BitAnd)
_COMPARES = (ast.Lt, ast.Gt, ast.LtE, ast.GtE, ast.Eq, ast.NotEq)
_MATH = {"nan": float("nan"), "inf": float("inf")}


def __getattr__(name: str) -> Any:
    """``VERSION``: this module's fingerprint, computed when a module is written.

    Written into every stub, so that a change to the lowering changes the generated
    modules' text and their caches are not reused. Not at import: no hashing at start-up.
    """
    if name != "VERSION":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import hashlib
    from pathlib import Path

    value = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]
    globals()["VERSION"] = value
    return value


def _function(source: str) -> ast.FunctionDef:
    tree = ast.parse(source)
    if len(tree.body) != 1 or not isinstance(tree.body[0], ast.FunctionDef):
        raise ValueError("expected the source of one function")
    return tree.body[0]


def supported(source: str, counts: tuple[str, ...] = ()) -> bool:
    """Whether :func:`lowered` translates the function in ``source`` (see the module).

    ``counts``: the arguments that are integers (loop counts), the others arrays.
    """
    fn = _function(source)
    if fn.args.vararg or fn.args.kwarg or fn.args.kwonlyargs or fn.args.defaults:
        return False
    names = [a.arg for a in fn.args.args]
    if not set(counts) <= set(names):
        return False
    check = _Check(set(names) - set(counts), None, counts)
    if len(fn.body) == 1 and isinstance(fn.body[0], ast.For):  # lanes: one loop, the body
        loop = fn.body[0]
        if _range_of(loop, counts) is None or not isinstance(loop.target, ast.Name):
            return False
        if loop.orelse or not check.name(loop.target.id) or loop.target.id in counts:
            return False
        check.loop = loop.target.id
        return all(check.statement(x) for x in loop.body)
    return all(check.statement(x) for x in fn.body)


def _range_of(loop: ast.For, counts: tuple[str, ...] = ()) -> int | str | None:
    """N of ``for l in range(N)``: a constant, or the name of an integer argument; else None."""
    it = loop.iter
    if not (
        isinstance(it, ast.Call)
        and isinstance(it.func, ast.Name)
        and it.func.id == "range"
        and len(it.args) == 1
        and not it.keywords
    ):
        return None
    n = it.args[0]
    if isinstance(n, ast.Constant) and type(n.value) is int:
        return n.value
    if isinstance(n, ast.Name) and n.id in counts:
        return n.id
    return None


class _Check:
    """The supported part of Python: ``arrays`` the arguments, ``loop`` the lanes' index.

    Every name read is assigned before on every path (``defined``), as the lowering needs.
    """

    def __init__(self, arrays: set[str], loop: str | None, counts: tuple[str, ...] = ()) -> None:
        self.arrays, self.loop, self.counts = arrays, loop, set(counts)
        self.defined = set(counts)  # read as integers, never assigned

    def name(self, n: str) -> bool:
        return n not in self.arrays and n != self.loop

    def statement(self, s: ast.stmt) -> bool:
        if isinstance(s, ast.Assign):
            if len(s.targets) != 1 or not self.expr(s.value):
                return False
            t = s.targets[0]
            if isinstance(t, ast.Name) and self.name(t.id) and t.id not in self.counts:
                self.defined.add(t.id)
                return True
            return self.element(t)
        if isinstance(s, ast.AugAssign):
            return (
                isinstance(s.target, ast.Name)
                and self.name(s.target.id)
                and s.target.id not in self.counts
                and s.target.id in self.defined
                and isinstance(s.op, _BINOPS)
                and self.expr(s.value)
            )
        if isinstance(s, ast.If):
            if not self.expr(s.test):
                return False
            before = set(self.defined)
            ok = all(self.statement(x) for x in s.body)
            after_body, self.defined = self.defined, before
            ok = ok and all(self.statement(x) for x in s.orelse)
            self.defined &= after_body
            return ok
        return False

    def element(self, t: ast.expr) -> bool:
        if not (isinstance(t, ast.Subscript) and isinstance(t.value, ast.Name)):
            return False
        if t.value.id not in self.arrays:
            return False
        index = t.slice.elts if isinstance(t.slice, ast.Tuple) else [t.slice]
        return all(self.index(i) for i in index)

    def index(self, i: ast.expr) -> bool:
        """A constant, or (in the loop) the loop's index plus a constant."""
        if isinstance(i, ast.Constant):
            return type(i.value) is int
        if self.loop is None:
            return False
        if isinstance(i, ast.Name):
            return i.id == self.loop
        return (
            isinstance(i, ast.BinOp)
            and isinstance(i.op, ast.Add)
            and {type(i.left), type(i.right)} == {ast.Constant, ast.Name}
            and all(
                (isinstance(x, ast.Name) and x.id == self.loop)
                or (isinstance(x, ast.Constant) and type(x.value) is int)
                for x in (i.left, i.right)
            )
        )

    def expr(self, e: ast.expr) -> bool:
        if isinstance(e, ast.Constant):
            return type(e.value) in (int, float)
        if isinstance(e, ast.Attribute):  # math.nan, math.inf
            return isinstance(e.value, ast.Name) and e.value.id == "math" and e.attr in _MATH
        if isinstance(e, ast.Name):
            return self.name(e.id) and e.id in self.defined
        if isinstance(e, ast.Subscript):
            return self.element(e)
        if isinstance(e, ast.BinOp):
            return isinstance(e.op, _BINOPS) and self.expr(e.left) and self.expr(e.right)
        if isinstance(e, ast.UnaryOp):
            return isinstance(e.op, ast.USub) and self.expr(e.operand)
        if isinstance(e, ast.Compare):
            return (
                len(e.ops) == 1
                and isinstance(e.ops[0], _COMPARES)
                and self.expr(e.left)
                and self.expr(e.comparators[0])
            )
        if isinstance(e, ast.IfExp):
            return all(self.expr(x) for x in (e.test, e.body, e.orelse))
        if isinstance(e, ast.Call):
            if not (isinstance(e.func, ast.Name) and not e.keywords):
                return False
            many = e.func.id in ("max", "min") and len(e.args) >= 2
            return (many or (e.func.id in _CALLS and len(e.args) == 1)) and all(
                self.expr(x) for x in e.args
            )
        return False


def lowered(name: str, args: tuple[str, ...], source: str, counts: tuple[str, ...] = ()) -> Any:
    """A numba intrinsic ``name_ir(*args)`` doing what the function in ``source`` does.

    Called from a jitted function of the same arguments: float64 arrays, and the integers
    named in ``counts`` (loop counts); returns nothing. ``source`` is read only when numba
    compiles a caller (a process that loads its callers from numba's cache parses nothing).

    Raises:
        ValueError: at compilation, a function outside the supported part of Python.
    """
    from numba.core import types
    from numba.extending import intrinsic

    parsed: list[list[ast.stmt]] = []

    def codegen(context: Any, builder: Any, signature: Any, values: Any) -> Any:
        if not parsed:
            fn = _function(source)
            if not supported(source, counts) or [a.arg for a in fn.args.args] != list(args):
                raise ValueError(f"{name}: outside the part of Python this module lowers")
            parsed.append(fn.body)
        given = dict(zip(args, zip(signature.args, values, strict=True), strict=True))
        emitter = _Emitter(context, builder, {k: v for k, v in given.items() if k not in counts})
        for k in counts:
            ty, value = given[k]
            emitter.values[k] = ("i", context.cast(builder, value, ty, types.int64))
        emitter.counts = counts
        emitter.block(parsed[0])
        return context.get_dummy_value()

    def typer(typingctx: Any, *tys: Any) -> Any:
        for arg, ty in zip(args, tys, strict=True):
            if arg in counts:
                if not isinstance(ty, types.Integer):
                    raise TypeError(f"{name}: argument {arg} must be an integer, not {ty}")
            elif not (isinstance(ty, types.Array) and ty.dtype == types.float64):
                raise TypeError(f"{name}: argument {arg} must be a float64 array, not {ty}")
        return types.void(*tys), codegen

    params = ", ".join(args)
    space: dict[str, Any] = {"typer": typer}
    exec(  # an intrinsic's typer takes its arguments by name: a function of their count
        f"def {name}_ir(typingctx, {params}):\n    return typer(typingctx, {params})\n", space
    )
    return intrinsic(space[f"{name}_ir"])


def stub(name: str, args: tuple[str, ...], source: str, counts: tuple[str, ...] = ()) -> str:
    """Module text: ``name`` as a jitted call of its :func:`lowered` body (``source``)."""
    params = ", ".join(args)
    text = f'"""\\\n{source}"""' if '"""' not in source and "\\" not in source else repr(source)
    more = f", counts={tuple(counts)!r}" if counts else ""
    version = globals().get("VERSION") or __getattr__("VERSION")  # a test may set it
    return (
        f"# lowered by rrt_pin.compiled._straight {version}\n"
        f"_{name}_ir = lowered({name!r}, {tuple(args)!r}, {text}{more})\n\n\n"
        f"@jit\ndef {name}({params}):\n    _{name}_ir({params})\n"
    )


def lowered_part(part: str) -> str:
    """A module's ``@jit`` function (its text) as a jitted call of its lowered body.

    A function outside the supported part of Python is returned as it is.
    """
    head, _, source = part.partition("\n")
    if head != "@jit" or not supported(source):
        return part
    m = re.match(r"def (\w+)\(([^)]*)\):", source)
    return stub(m[1], tuple(a.strip() for a in m[2].split(",")), source)


class _Emitter:
    """LLVM IR for a supported body, with numba's context and builder (see the module)."""

    def __init__(self, context: Any, builder: Any, arrays: dict[str, tuple[Any, Any]]) -> None:
        from llvmlite import ir

        self.ir, self.context, self.builder = ir, context, builder
        self.double, self.int = ir.DoubleType(), ir.IntType(64)
        self.arrays = {
            name: (ty, context.make_array(ty)(context, builder, value))
            for name, (ty, value) in arrays.items()
        }
        self.values: dict[str, tuple[str, Any]] = {}  # name -> (kind "f" | "i" | "b", value)
        self.counts: tuple[str, ...] = ()  # the integer arguments (loop counts)

    # ---------------------------------------------------------------- statements
    def block(self, statements: list[ast.stmt]) -> None:
        for s in statements:
            self.statement(s)

    def statement(self, s: ast.stmt) -> None:
        if isinstance(s, ast.For):
            self.loop(s)
        elif isinstance(s, ast.Assign):
            target, value = s.targets[0], self.expr(s.value)
            if isinstance(target, ast.Name):
                self.values[target.id] = value
            else:
                self.builder.store(self.as_float(value), self.element(target))
        elif isinstance(s, ast.AugAssign):
            name = s.target.id
            self.values[name] = self.binop(s.op, self.values[name], self.expr(s.value))
        else:
            self.branches(s)

    def loop(self, s: ast.For) -> None:
        """``for l in range(N)``: LLVM's counted loop (as numba's), its names its own."""
        from numba.core import cgutils

        before = dict(self.values)
        n = _range_of(s, self.counts)
        count = self.ir.Constant(self.int, n) if isinstance(n, int) else self.values[n][1]
        with cgutils.for_range(self.builder, count) as loop:
            self.values[s.target.id] = ("i", loop.index)
            self.block(s.body)
        self.values = before

    def branches(self, s: ast.If) -> None:
        before = dict(self.values)
        with self.builder.if_else(self.truth(self.expr(s.test))) as (then, otherwise):
            with then:
                self.block(s.body)
                then_values, then_end = self.values, self.builder.block
            self.values = dict(before)
            with otherwise:
                self.block(s.orelse)
                else_values, else_end = self.values, self.builder.block
        merged = {}
        for name in then_values.keys() & else_values.keys():
            a, b = then_values[name], else_values[name]
            if a is b:
                merged[name] = a
                continue
            if a[0] != b[0]:
                a, b = ("f", self.as_float(a)), ("f", self.as_float(b))
            phi = self.builder.phi(a[1].type)
            phi.add_incoming(a[1], then_end)
            phi.add_incoming(b[1], else_end)
            merged[name] = (a[0], phi)
        self.values = merged

    # ---------------------------------------------------------------- expressions
    def element(self, e: ast.Subscript) -> Any:
        from numba.core import cgutils

        ty, ary = self.arrays[e.value.id]
        index = e.slice.elts if isinstance(e.slice, ast.Tuple) else [e.slice]
        inds = [self.offset(i) for i in index]
        if ty.ndim == 1 and ty.is_c_contig:  # in bounds, no wrap: consecutive lanes
            return self.builder.gep(ary.data, inds, inbounds=True)
        return cgutils.get_item_pointer(self.context, self.builder, ty, ary, inds)

    def offset(self, i: ast.expr) -> Any:
        """An index: a constant, or the loop's index plus one (never wraps: ``nsw``)."""
        if isinstance(i, ast.Constant):
            return self.ir.Constant(self.int, i.value)
        if isinstance(i, ast.Name):
            return self.values[i.id][1]
        return self.builder.add(self.offset(i.left), self.offset(i.right), flags=["nsw"])

    def expr(self, e: ast.expr) -> tuple[str, Any]:
        b, ir = self.builder, self.ir
        if isinstance(e, ast.Constant):
            if type(e.value) is int:
                return "i", ir.Constant(self.int, e.value)
            return "f", ir.Constant(self.double, e.value)
        if isinstance(e, ast.Name):
            return self.values[e.id]
        if isinstance(e, ast.Attribute):
            return "f", ir.Constant(self.double, _MATH[e.attr])
        if isinstance(e, ast.Subscript):
            return "f", b.load(self.element(e))
        if isinstance(e, ast.BinOp):
            return self.binop(e.op, self.expr(e.left), self.expr(e.right))
        if isinstance(e, ast.UnaryOp):
            kind, v = self.expr(e.operand)
            return (kind, b.fneg(v)) if kind == "f" else ("i", b.neg(self.as_int(kind, v)))
        if isinstance(e, ast.Compare):
            return self.compare(e.ops[0], self.expr(e.left), self.expr(e.comparators[0]))
        if isinstance(e, ast.IfExp):
            test = self.truth(self.expr(e.test))
            x, y = self.expr(e.body), self.expr(e.orelse)
            if x[0] != y[0]:
                x, y = ("f", self.as_float(x)), ("f", self.as_float(y))
            return x[0], b.select(test, x[1], y[1])
        if e.func.id in ("max", "min"):  # numba's: left to right, select(v > acc, v, acc)
            acc = self.expr(e.args[0])
            for arg in e.args[1:]:
                v = self.expr(arg)
                if v[0] != acc[0]:
                    v, acc = ("f", self.as_float(v)), ("f", self.as_float(acc))
                pred = self.compare(ast.Gt() if e.func.id == "max" else ast.Lt(), v, acc)[1]
                acc = (acc[0], b.select(pred, v[1], acc[1]))
            return acc
        return self.call(e.func.id, self.expr(e.args[0]))

    def binop(self, op: ast.operator, x: tuple[str, Any], y: tuple[str, Any]) -> tuple[str, Any]:
        b = self.builder
        if isinstance(op, ast.BitAnd):
            return "i", b.and_(self.as_int(*x), self.as_int(*y))
        if x[0] != "f" and y[0] != "f" and not isinstance(op, ast.Div):
            f = {ast.Add: b.add, ast.Sub: b.sub, ast.Mult: b.mul}[type(op)]
            return "i", f(self.as_int(*x), self.as_int(*y))
        f = {ast.Add: b.fadd, ast.Sub: b.fsub, ast.Mult: b.fmul, ast.Div: b.fdiv}[type(op)]
        return "f", f(self.as_float(x), self.as_float(y))

    def compare(self, op: ast.cmpop, x: tuple[str, Any], y: tuple[str, Any]) -> tuple[str, Any]:
        sign = {ast.Lt: "<", ast.Gt: ">", ast.LtE: "<=", ast.GtE: ">=", ast.Eq: "==",
                ast.NotEq: "!="}[type(op)]  # fmt: skip
        if x[0] == "f" or y[0] == "f":  # as numba: ordered, but != is unordered (NaN != NaN)
            cmp = self.builder.fcmp_unordered if sign == "!=" else self.builder.fcmp_ordered
            return "b", cmp(sign, self.as_float(x), self.as_float(y))
        return "b", self.builder.icmp_signed(sign, self.as_int(*x), self.as_int(*y))

    def call(self, name: str, x: tuple[str, Any]) -> tuple[str, Any]:
        b = self.builder
        if name == "int":
            return ("i", self.as_int(*x)) if x[0] != "f" else ("i", b.fptosi(x[1], self.int))
        if name == "float":
            return "f", self.as_float(x)
        if name == "abs" and x[0] != "f":
            v = self.as_int(*x)
            return "i", b.select(b.icmp_signed("<", v, v.type(0)), b.neg(v), v)
        v = self.as_float(x)
        module = b.module
        if name in ("sqrt", "tanh"):  # numba calls libm's
            fnty = self.ir.FunctionType(self.double, [self.double])
            fn = module.globals.get(name) or self.ir.Function(module, fnty, name)
            return "f", b.call(fn, [v])
        intrinsic = {"abs": "llvm.fabs", "sin": "llvm.sin", "cos": "llvm.cos"}[name]
        return "f", b.call(module.declare_intrinsic(intrinsic, [self.double]), [v])

    # ---------------------------------------------------------------- conversions
    def as_float(self, x: tuple[str, Any]) -> Any:
        kind, v = x
        if kind == "f":
            return v
        return self.builder.sitofp(self.as_int(kind, v), self.double)

    def as_int(self, kind: str, v: Any) -> Any:
        if kind == "i":
            return v
        if kind == "b":
            return self.builder.zext(v, self.int)
        raise TypeError("a float where an integer is needed (& or an int operation)")

    def truth(self, x: tuple[str, Any]) -> Any:
        kind, v = x
        if kind == "b":
            return v
        if kind == "i":
            return self.builder.icmp_signed("!=", v, v.type(0))
        return self.builder.fcmp_unordered("!=", v, v.type(0.0))
