//! Maximum flow and minimum s-t cut by the Boykov-Kolmogorov method (Boykov and
//! Kolmogorov, "An Experimental Comparison of Min-Cut/Max-Flow Algorithms for Energy
//! Minimization in Vision", PAMI 2004): two search trees, one from the source and one
//! from the sink, grow until they touch; the path found is augmented, the nodes it cut
//! off are adopted by another parent of their tree or set free, and the trees are kept
//! between augmentations. On pixel grids, whose paths are short and many, it is far
//! faster than breadth-first augmenting paths (Edmonds-Karp), which start from nothing
//! each time.
//!
//! Each node may have a capacity from the source and one to the sink (its terminal
//! arcs); arcs between nodes come in pairs (an arc and its reverse at the index with the
//! last bit flipped), so that a residual capacity is a single number per arc.

use std::collections::VecDeque;

/// `parent` of a node in no tree.
const NONE: u32 = u32::MAX;
/// `parent` of a node linked straight to its tree's terminal.
const TERMINAL: u32 = u32::MAX - 1;
/// `parent` of a node whose link to its tree was cut, waiting for adoption.
const ORPHAN: u32 = u32::MAX - 2;

const FREE: u8 = 0;
const SOURCE: u8 = 1;
const SINK: u8 = 2;

/// A graph of nodes with terminal capacities and pairs of arcs between them, and its
/// maximum flow.
#[derive(Clone, Debug, Default)]
pub struct FlowGraph {
    /// Residual capacity from the source (positive) or to the sink (negative).
    terminal: Vec<f32>,
    /// The first arc out of each node (`NONE`: none).
    first: Vec<u32>,
    /// Each arc's head node.
    head: Vec<u32>,
    /// The next arc out of the same node.
    next: Vec<u32>,
    /// Each arc's residual capacity.
    cap: Vec<f32>,
    tree: Vec<u8>,
    /// The arc from a node to its parent in its tree, or `NONE`, `TERMINAL`, `ORPHAN`.
    parent: Vec<u32>,
    /// When a node's distance to its terminal was last known to hold, and the distance.
    stamp: Vec<u32>,
    dist: Vec<u32>,
    queued: Vec<bool>,
    active: VecDeque<u32>,
    orphans: VecDeque<u32>,
    time: u32,
    flow: f64,
}

impl FlowGraph {
    /// A graph of `nodes` nodes without arcs, with room for `arc_pairs` pairs of arcs.
    pub fn new(nodes: usize, arc_pairs: usize) -> Self {
        FlowGraph {
            terminal: vec![0.0; nodes],
            first: vec![NONE; nodes],
            head: Vec::with_capacity(2 * arc_pairs),
            next: Vec::with_capacity(2 * arc_pairs),
            cap: Vec::with_capacity(2 * arc_pairs),
            tree: vec![FREE; nodes],
            parent: vec![NONE; nodes],
            stamp: vec![0; nodes],
            dist: vec![0; nodes],
            queued: vec![false; nodes],
            ..FlowGraph::default()
        }
    }

    /// Adds capacities from the source to node `i` and from it to the sink (both at least
    /// 0); what both carry is flow already, so only their difference is kept.
    pub fn add_terminal(&mut self, i: usize, source: f32, sink: f32) {
        let (mut source, mut sink) = (source, sink);
        let t = self.terminal[i];
        if t > 0.0 {
            source += t;
        } else {
            sink -= t;
        }
        self.flow += f64::from(source.min(sink));
        self.terminal[i] = source - sink;
    }

    /// Adds an arc from `i` to `j` of capacity `cap` and its reverse of capacity `rev`.
    pub fn add_edge(&mut self, i: usize, j: usize, cap: f32, rev: f32) {
        for (from, to, c) in [(i, j, cap), (j, i, rev)] {
            let a = self.head.len() as u32;
            self.head.push(to as u32);
            self.next.push(self.first[from]);
            self.cap.push(c);
            self.first[from] = a;
        }
    }

    /// Whether node `i` is on the source's side of the minimum cut (call after
    /// [`FlowGraph::maxflow`]): those the source still reaches through residual arcs.
    pub fn is_source(&self, i: usize) -> bool {
        self.tree[i] == SOURCE
    }

    /// Computes the maximum flow, and so the minimum cut; returns its value.
    pub fn maxflow(&mut self) -> f64 {
        for i in 0..self.terminal.len() {
            let t = self.terminal[i];
            if t != 0.0 {
                self.tree[i] = if t > 0.0 { SOURCE } else { SINK };
                self.parent[i] = TERMINAL;
                self.dist[i] = 1;
                self.activate(i as u32);
            }
        }
        while let Some(i) = self.active.pop_front() {
            self.queued[i as usize] = false;
            if self.tree[i as usize] == FREE {
                continue;
            }
            if let Some(a) = self.grow(i) {
                // i may have more paths: it is looked at again first
                self.queued[i as usize] = true;
                self.active.push_front(i);
                self.time += 1;
                self.augment(a);
                self.adopt();
            }
        }
        self.flow
    }

    fn activate(&mut self, i: u32) {
        if !self.queued[i as usize] {
            self.queued[i as usize] = true;
            self.active.push_back(i);
        }
    }

    /// Grows `i`'s tree over its free neighbours; returns the arc (from the source's tree
    /// to the sink's) where it meets the other tree, if it does.
    fn grow(&mut self, i: u32) -> Option<u32> {
        let iu = i as usize;
        let from_source = self.tree[iu] == SOURCE;
        let mut a = self.first[iu];
        while a != NONE {
            let au = a as usize;
            let j = self.head[au] as usize;
            // the arc that carries flow away from the terminal: i -> j in the source's
            // tree, j -> i in the sink's
            let open = if from_source {
                self.cap[au] > 0.0
            } else {
                self.cap[au ^ 1] > 0.0
            };
            if open {
                match self.tree[j] {
                    FREE => {
                        self.tree[j] = self.tree[iu];
                        self.parent[j] = a ^ 1;
                        self.stamp[j] = self.stamp[iu];
                        self.dist[j] = self.dist[iu] + 1;
                        self.activate(j as u32);
                    }
                    t if t != self.tree[iu] => return Some(if from_source { a } else { a ^ 1 }),
                    _ => {
                        // a shorter way to the terminal through i
                        if self.stamp[j] <= self.stamp[iu] && self.dist[j] > self.dist[iu] {
                            self.parent[j] = a ^ 1;
                            self.stamp[j] = self.stamp[iu];
                            self.dist[j] = self.dist[iu] + 1;
                        }
                    }
                }
            }
            a = self.next[au];
        }
        None
    }

    /// Pushes the most the path through arc `a` (source's tree to sink's) carries, and
    /// makes orphans of the nodes whose link to their tree it saturates.
    fn augment(&mut self, a: u32) {
        let s = self.head[(a ^ 1) as usize];
        let t = self.head[a as usize];
        let mut push = self.cap[a as usize];
        let mut x = s;
        loop {
            let p = self.parent[x as usize];
            if p == TERMINAL {
                push = push.min(self.terminal[x as usize]);
                break;
            }
            push = push.min(self.cap[(p ^ 1) as usize]);
            x = self.head[p as usize];
        }
        let mut x = t;
        loop {
            let p = self.parent[x as usize];
            if p == TERMINAL {
                push = push.min(-self.terminal[x as usize]);
                break;
            }
            push = push.min(self.cap[p as usize]);
            x = self.head[p as usize];
        }

        self.cap[a as usize] -= push;
        self.cap[(a ^ 1) as usize] += push;
        let mut x = s;
        loop {
            let p = self.parent[x as usize];
            if p == TERMINAL {
                self.terminal[x as usize] -= push;
                if self.terminal[x as usize] <= 0.0 {
                    self.orphan(x);
                }
                break;
            }
            self.cap[(p ^ 1) as usize] -= push;
            self.cap[p as usize] += push;
            let up = self.head[p as usize];
            if self.cap[(p ^ 1) as usize] <= 0.0 {
                self.orphan(x);
            }
            x = up;
        }
        let mut x = t;
        loop {
            let p = self.parent[x as usize];
            if p == TERMINAL {
                self.terminal[x as usize] += push;
                if self.terminal[x as usize] >= 0.0 {
                    self.orphan(x);
                }
                break;
            }
            self.cap[p as usize] -= push;
            self.cap[(p ^ 1) as usize] += push;
            let up = self.head[p as usize];
            if self.cap[p as usize] <= 0.0 {
                self.orphan(x);
            }
            x = up;
        }
        self.flow += f64::from(push);
    }

    fn orphan(&mut self, x: u32) {
        self.parent[x as usize] = ORPHAN;
        self.orphans.push_back(x);
    }

    /// The distance from `j` to its tree's terminal, if its chain of parents still reaches
    /// it; marks the chain with the current time.
    fn origin(&mut self, j: u32) -> Option<u32> {
        let mut d = 0;
        let mut x = j;
        loop {
            let xu = x as usize;
            if self.stamp[xu] == self.time {
                d += self.dist[xu];
                break;
            }
            let p = self.parent[xu];
            d += 1;
            if p == TERMINAL {
                self.stamp[xu] = self.time;
                self.dist[xu] = 1;
                break;
            }
            if p == ORPHAN || p == NONE {
                return None;
            }
            x = self.head[p as usize];
        }
        let (mut x, mut dd) = (j, d);
        while self.stamp[x as usize] != self.time {
            self.stamp[x as usize] = self.time;
            self.dist[x as usize] = dd;
            dd -= 1;
            x = self.head[self.parent[x as usize] as usize];
        }
        Some(d)
    }

    /// Gives every orphan a parent in its tree that still reaches the terminal, or sets
    /// it free (its children become orphans, its neighbours that could take it active).
    fn adopt(&mut self) {
        while let Some(o) = self.orphans.pop_front() {
            let ou = o as usize;
            let tree = self.tree[ou];
            let mut best = (NONE, u32::MAX);
            let mut a = self.first[ou];
            while a != NONE {
                let open = if tree == SOURCE {
                    self.cap[(a ^ 1) as usize] > 0.0
                } else {
                    self.cap[a as usize] > 0.0
                };
                let j = self.head[a as usize];
                if open
                    && self.tree[j as usize] == tree
                    && let Some(d) = self.origin(j)
                    && d < best.1
                {
                    best = (a, d);
                }
                a = self.next[a as usize];
            }
            if best.0 != NONE {
                self.parent[ou] = best.0;
                self.stamp[ou] = self.time;
                self.dist[ou] = best.1 + 1;
                continue;
            }
            let mut a = self.first[ou];
            while a != NONE {
                let j = self.head[a as usize];
                let ju = j as usize;
                let open = if tree == SOURCE {
                    self.cap[(a ^ 1) as usize] > 0.0
                } else {
                    self.cap[a as usize] > 0.0
                };
                a = self.next[a as usize];
                if self.tree[ju] != tree {
                    continue;
                }
                if open {
                    self.activate(j);
                }
                let p = self.parent[ju];
                if p != TERMINAL && p != ORPHAN && p != NONE && self.head[p as usize] == o {
                    self.orphan(j);
                }
            }
            self.tree[ou] = FREE;
            self.parent[ou] = NONE;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::splitmix::SplitMix;

    /// The cost of the cut that puts the nodes of `side` (bit i: node i) on the source's.
    fn cut_cost(
        n: usize,
        terminals: &[(f32, f32)],
        edges: &[(usize, usize, f32, f32)],
        side: u32,
    ) -> f64 {
        let on = |i: usize| side >> i & 1 == 1;
        let mut c = 0.0;
        for (i, &(s, t)) in terminals.iter().enumerate().take(n) {
            c += f64::from(if on(i) { t } else { s });
        }
        for &(i, j, a, b) in edges {
            if on(i) && !on(j) {
                c += f64::from(a);
            }
            if on(j) && !on(i) {
                c += f64::from(b);
            }
        }
        c
    }

    #[test]
    fn the_flow_is_the_brute_force_minimum_cut() {
        let mut rng = SplitMix(7);
        for case in 0..400 {
            let n = 2 + rng.below(9);
            let terminals: Vec<(f32, f32)> = (0..n)
                .map(|_| {
                    let mut v = || {
                        if rng.uniform() < 0.4 {
                            0.0
                        } else {
                            (rng.uniform() * 10.0) as f32
                        }
                    };
                    (v(), v())
                })
                .collect();
            let mut edges = Vec::new();
            for _ in 0..rng.below(3 * n) + 1 {
                let (i, j) = (rng.below(n), rng.below(n));
                if i != j {
                    let c = (rng.uniform() * 8.0) as f32;
                    let r = if rng.uniform() < 0.3 {
                        0.0
                    } else {
                        (rng.uniform() * 8.0) as f32
                    };
                    edges.push((i, j, c, r));
                }
            }
            let mut g = FlowGraph::new(n, edges.len());
            for (i, &(s, t)) in terminals.iter().enumerate() {
                g.add_terminal(i, s, t);
            }
            for &(i, j, c, r) in &edges {
                g.add_edge(i, j, c, r);
            }
            let flow = g.maxflow();
            let best = (0..1u32 << n)
                .map(|s| cut_cost(n, &terminals, &edges, s))
                .fold(f64::INFINITY, f64::min);
            let side = (0..n).fold(0, |s, i| s | u32::from(g.is_source(i)) << i);
            let found = cut_cost(n, &terminals, &edges, side);
            // sums of at most ~40 f32 capacities below 10: 1e-3 is far above their rounding
            assert!(
                (flow - best).abs() < 1e-3,
                "case {case}: flow {flow}, min cut {best}"
            );
            assert!(
                (found - best).abs() < 1e-3,
                "case {case}: cut {found}, min cut {best}"
            );
        }
    }

    #[test]
    fn a_grid_splits_along_its_weakest_column() {
        // 6 x 4, source on the left column, sink on the right; column 3 -> 4 weak
        let (w, h) = (6, 4);
        let mut g = FlowGraph::new(w * h, 2 * w * h);
        for y in 0..h {
            g.add_terminal(y * w, 100.0, 0.0);
            g.add_terminal(y * w + w - 1, 0.0, 100.0);
            for x in 0..w - 1 {
                let c = if x == 3 { 1.0 } else { 5.0 };
                g.add_edge(y * w + x, y * w + x + 1, c, c);
            }
        }
        assert_eq!(g.maxflow(), 4.0);
        for i in 0..w * h {
            assert_eq!(g.is_source(i), i % w <= 3);
        }
    }
}
