//! Operations per lit pair, from naga's IR of each gather pass as assembled (workgroup
//! tiles), orthographic camera, 3 active lobes: the statements of the orthographic pair loop
//! (the first loop inside the tile loop: the `perspective == 0` branch comes first), with
//! every call inlined and every loop inside it (the lobe loop) counted 3 times. Each
//! expression counts once per component of its result (dot: once per component of its
//! operands), a float add or subtract of a product used nowhere else counts with that
//! product as one fused multiply-add; swizzles, accesses, constructors and literals are free.
//! Branches: the path takes the costlier side of each (what follows a side that returns,
//! breaks or continues is not on that side's path), except, for grey lobes, the branches on
//! what the channels share (`shared_*`), where it takes the cheaper; "all" adds both sides
//! of every branch. Loads from memory (the tile, the parameters) are counted apart; integer
//! operations are mostly the IR's index arithmetic, which a backend compiler folds.

use super::validated;
use matedit::gpu::{Pass, Tiles};

const LOBES: u32 = 3;

/// Scalar operations, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Ops {
    /// Float add, multiply, fused multiply-add, min/max/abs/clamp/floor, compare, select.
    fp: u32,
    /// Division, exp, exp2, log, log2, sqrt, atan2 and the other special functions.
    special: u32,
    /// Integer and boolean arithmetic (indices, loop counters, masks).
    int: u32,
    /// Loads from memory (the tile, the parameters), not from local variables.
    loads: u32,
}

impl Ops {
    fn alu(&self) -> u32 {
        self.fp + self.special + self.int
    }

    fn plus(self, o: Ops) -> Ops {
        Ops {
            fp: self.fp + o.fp,
            special: self.special + o.special,
            int: self.int + o.int,
            loads: self.loads + o.loads,
        }
    }

    fn times(self, k: u32) -> Ops {
        Ops {
            fp: self.fp * k,
            special: self.special * k,
            int: self.int * k,
            loads: self.loads * k,
        }
    }
}

/// The operations of a block: along its longest path (one side of each branch: what a lane
/// issues when its neighbours go the same way) and over every statement (both sides: what
/// a fully divergent group issues).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Count {
    path: Ops,
    all: Ops,
}

impl Count {
    fn plus(self, o: Count) -> Count {
        Count {
            path: self.path.plus(o.path),
            all: self.all.plus(o.all),
        }
    }

    fn times(self, k: u32) -> Count {
        Count {
            path: self.path.times(k),
            all: self.all.times(k),
        }
    }
}

struct Counter<'a> {
    module: &'a naga::Module,
    info: &'a naga::valid::ModuleInfo,
    /// Every lobe grey (the same scale and exponent in the three channels): the path takes
    /// the shorter side of the branches in `shared_*`.
    grey: bool,
}

impl Counter<'_> {
    fn inner<'b>(
        &'b self,
        fi: &'b naga::valid::FunctionInfo,
        h: naga::Handle<naga::Expression>,
    ) -> &'b naga::TypeInner {
        fi[h].ty.inner_with(&self.module.types)
    }

    fn width(&self, fi: &naga::valid::FunctionInfo, h: naga::Handle<naga::Expression>) -> u32 {
        match *self.inner(fi, h) {
            naga::TypeInner::Vector { size, .. } => size as u32,
            _ => 1,
        }
    }

    fn is_float(&self, fi: &naga::valid::FunctionInfo, h: naga::Handle<naga::Expression>) -> bool {
        self.inner(fi, h).scalar_kind() == Some(naga::ScalarKind::Float)
    }

    /// Whether `h` is a float product used only once (fused into the add that uses it).
    fn fusable(
        &self,
        f: &naga::Function,
        fi: &naga::valid::FunctionInfo,
        h: naga::Handle<naga::Expression>,
    ) -> bool {
        matches!(
            f.expressions[h],
            naga::Expression::Binary {
                op: naga::BinaryOperator::Multiply,
                ..
            }
        ) && self.is_float(fi, h)
            && fi[h].ref_count == 1
    }

    fn expression(
        &self,
        f: &naga::Function,
        fi: &naga::valid::FunctionInfo,
        h: naga::Handle<naga::Expression>,
    ) -> Ops {
        use naga::{BinaryOperator as B, Expression as E, MathFunction as M};
        let w = self.width(fi, h);
        let fp = |n| Ops {
            fp: n,
            ..Ops::default()
        };
        let special = |n| Ops {
            special: n,
            ..Ops::default()
        };
        let int = |n| Ops {
            int: n,
            ..Ops::default()
        };
        match f.expressions[h] {
            E::Load { pointer } if Self::global(f, pointer) => Ops {
                loads: 1,
                ..Ops::default()
            },
            // and, or, not with a constant: folded away
            E::Binary {
                op: B::LogicalAnd | B::LogicalOr,
                left,
                right,
            } if self.constant(f, left).is_some() || self.constant(f, right).is_some() => {
                Ops::default()
            }
            E::Unary { expr, .. } if self.constant(f, expr).is_some() => Ops::default(),
            E::Binary { op, left, right } => {
                if !self.is_float(fi, left) {
                    int(w)
                } else if op == B::Divide {
                    special(w)
                } else if matches!(op, B::Add | B::Subtract)
                    && (self.fusable(f, fi, left) || self.fusable(f, fi, right))
                {
                    Ops::default()
                } else {
                    fp(w)
                }
            }
            E::Unary { expr, .. } | E::As { expr, .. } => {
                if self.is_float(fi, expr) || self.is_float(fi, h) {
                    fp(w)
                } else {
                    int(w)
                }
            }
            E::Select { .. } => {
                if self.is_float(fi, h) {
                    fp(w)
                } else {
                    int(w)
                }
            }
            E::Relational { .. } => int(1),
            E::Math { fun, arg, .. } => match fun {
                M::Dot => fp(self.width(fi, arg)),
                M::Length => fp(self.width(fi, arg)).plus(special(1)),
                M::Exp
                | M::Exp2
                | M::Log
                | M::Log2
                | M::Sqrt
                | M::InverseSqrt
                | M::Atan2
                | M::Pow
                | M::Sin
                | M::Cos
                | M::Tan
                | M::Atan
                | M::Acos
                | M::Asin => special(w),
                M::Normalize => fp(2 * self.width(fi, arg)).plus(special(1)),
                _ if self.is_float(fi, h) => fp(w),
                _ => int(w),
            },
            _ => Ops::default(),
        }
    }

    /// The value of `h` where it is a constant boolean (`BRANCHES`, or its negation).
    fn constant(&self, f: &naga::Function, h: naga::Handle<naga::Expression>) -> Option<bool> {
        match f.expressions[h] {
            naga::Expression::Literal(naga::Literal::Bool(b)) => Some(b),
            naga::Expression::Constant(c) => {
                match self.module.global_expressions[self.module.constants[c].init] {
                    naga::Expression::Literal(naga::Literal::Bool(b)) => Some(b),
                    _ => None,
                }
            }
            naga::Expression::Unary {
                op: naga::UnaryOperator::LogicalNot,
                expr,
            } => self.constant(f, expr).map(|b| !b),
            _ => None,
        }
    }

    /// Whether `pointer` points into a global variable (memory), not a local one.
    fn global(f: &naga::Function, pointer: naga::Handle<naga::Expression>) -> bool {
        match f.expressions[pointer] {
            naga::Expression::GlobalVariable(_) => true,
            naga::Expression::Access { base, .. } | naga::Expression::AccessIndex { base, .. } => {
                Self::global(f, base)
            }
            _ => false,
        }
    }

    fn block(
        &self,
        f: &naga::Function,
        fi: &naga::valid::FunctionInfo,
        block: &[naga::Statement],
    ) -> Count {
        self.flow(f, fi, block).count()
    }

    /// The paths through `sts`: the costliest that leaves the block (return, break,
    /// continue), the costliest that reaches its end, and the cost of every statement.
    fn flow(
        &self,
        f: &naga::Function,
        fi: &naga::valid::FunctionInfo,
        sts: &[naga::Statement],
    ) -> Flow {
        use naga::Statement as S;
        let Some((st, rest)) = sts.split_first() else {
            return Flow::through(Ops::default());
        };
        let here = match st {
            S::Emit(range) => Flow::through(
                range
                    .clone()
                    .map(|h| self.expression(f, fi, h))
                    .fold(Ops::default(), Ops::plus),
            ),
            S::Block(b) => self.flow(f, fi, b),
            // a constant condition (`BRANCHES`): the other side is folded away
            S::If {
                condition,
                accept,
                reject,
            } if self.constant(f, *condition).is_some() => {
                let taken = self.constant(f, *condition) == Some(true);
                self.flow(f, fi, if taken { accept } else { reject })
            }
            S::If { accept, reject, .. } => {
                let (a, r) = (self.flow(f, fi, accept), self.flow(f, fi, reject));
                let cheaper =
                    self.grey && f.name.as_deref().is_some_and(|n| n.starts_with("shared_"));
                if cheaper {
                    let all = a.all.plus(r.all);
                    let side = if a.count().path.alu() <= r.count().path.alu() {
                        a
                    } else {
                        r
                    };
                    Flow { all, ..side }
                } else {
                    Flow {
                        leave: costlier(a.leave, r.leave),
                        through: costlier(a.through, r.through),
                        all: a.all.plus(r.all),
                    }
                }
            }
            S::Loop {
                body, continuing, ..
            } => {
                let c = self
                    .block(f, fi, body)
                    .plus(self.block(f, fi, continuing))
                    .times(LOBES);
                Flow {
                    leave: None,
                    through: Some(c.path),
                    all: c.all,
                }
            }
            S::Call { function, .. } => {
                let callee = &self.module.functions[*function];
                let c = self.block(callee, &self.info[*function], &callee.body);
                Flow {
                    leave: None,
                    through: Some(c.path),
                    all: c.all,
                }
            }
            S::Return { .. } | S::Break | S::Continue => Flow {
                leave: Some(Ops::default()),
                through: None,
                all: Ops::default(),
            },
            _ => Flow::through(Ops::default()),
        };
        let after = self.flow(f, fi, rest);
        let then = |p: Option<Ops>, q: Option<Ops>| Some(p?.plus(q?));
        Flow {
            leave: costlier(here.leave, then(here.through, after.leave)),
            through: then(here.through, after.through),
            // after a statement that always leaves, the rest is never reached
            all: if here.through.is_some() {
                here.all.plus(after.all)
            } else {
                here.all
            },
        }
    }
}

/// The paths through a block of statements (see `Counter::flow`).
#[derive(Clone, Copy, Debug)]
struct Flow {
    leave: Option<Ops>,
    through: Option<Ops>,
    all: Ops,
}

impl Flow {
    fn through(ops: Ops) -> Flow {
        Flow {
            leave: None,
            through: Some(ops),
            all: ops,
        }
    }

    /// The costliest path, whichever way it ends, and every statement.
    fn count(self) -> Count {
        Count {
            path: costlier(self.leave, self.through).unwrap_or_default(),
            all: self.all,
        }
    }
}

fn costlier(a: Option<Ops>, b: Option<Ops>) -> Option<Ops> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.alu() > a.alu() { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// The first loop nested `depth` loops deep in `block`, in source order.
fn nested_loop(block: &naga::Block, depth: u32) -> Option<(&naga::Block, &naga::Block)> {
    use naga::Statement as S;
    for st in block.iter() {
        let found = match st {
            S::Block(b) => nested_loop(b, depth),
            S::If { accept, reject, .. } => {
                nested_loop(accept, depth).or_else(|| nested_loop(reject, depth))
            }
            S::Loop {
                body, continuing, ..
            } if depth == 0 => Some((body, continuing)),
            S::Loop { body, .. } => nested_loop(body, depth - 1),
            _ => None,
        };
        if found.is_some() {
            return found;
        }
    }
    None
}

/// The operations of one lit pair of `pass` (orthographic camera, 3 lobes, `grey`: every
/// lobe the same in the three channels).
fn pair_ops(pass: Pass, grey: bool) -> Count {
    let (module, info) = validated(pass, Tiles::Workgroup);
    let ep = &module.entry_points[0];
    let (body, continuing) = nested_loop(&ep.function.body, 1)
        .unwrap_or_else(|| panic!("{}: no pair loop", pass.name()));
    let c = Counter {
        module: &module,
        info: &info,
        grey,
    };
    let fi = info.get_entry_point(0);
    c.block(&ep.function, fi, body)
        .plus(c.block(&ep.function, fi, continuing))
}

/// Prints the operations per lit pair of each gather pass
/// (`cargo test --release --test it shaders::op_counts -- --nocapture`) and holds
/// them under bounds, so that a change that adds work to the pair loop fails here.
#[test]
fn pair_loop_op_counts() {
    println!(
        "operations per lit pair, orthographic camera, {LOBES} lobes (path: one side of each branch; all: both)"
    );
    println!(
        "{:<16} {:<14} {:>5} {:>5} {:>8} {:>5} {:>6} | {:>5} {:>8}",
        "pass", "lobes", "alu", "fp", "special", "int", "loads", "all", "special"
    );
    // (pass, grey, bound on the path's alu)
    for (pass, grey, bound) in [
        (Pass::Forward, false, 177),
        (Pass::Forward, true, 114),
        (Pass::BackwardNormal, false, 232),
        (Pass::BackwardNormal, true, 169),
        (Pass::BackwardTexel, false, 182),
        (Pass::BackwardTexel, true, 102),
    ] {
        let c = pair_ops(pass, grey);
        let p = c.path;
        println!(
            "{:<16} {:<14} {:>5} {:>5} {:>8} {:>5} {:>6} | {:>5} {:>8}",
            pass.name(),
            if grey { "grey" } else { "channels apart" },
            p.alu(),
            p.fp,
            p.special,
            p.int,
            p.loads,
            // both sides of every branch: the same whatever the lobes
            if grey {
                "-".to_string()
            } else {
                c.all.alu().to_string()
            },
            if grey {
                "-".to_string()
            } else {
                c.all.special.to_string()
            },
        );
        assert!(
            p.alu() <= bound,
            "{} ({}): {} operations per pair, over {bound}",
            pass.name(),
            if grey { "grey" } else { "channels apart" },
            p.alu()
        );
    }
}
