//! The connected components of the bipartite graph of eligible edges (union-find over the a's,
//! then the b's): each component's size sets its "unmatched" cost in the exact solve, and a
//! component too large to solve exactly is matched greedily. The buffers are kept between
//! calls, as the solver's are, and hold 32-bit node indices.

use super::sparse::trim;
use super::Edge;

/// One component: its a's and b's that have an edge, its largest edge cost, and whether it has
/// more possible pairs than the exact solve takes.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub(super) struct Extent {
    /// The component's a's with an edge.
    pub a: u32,
    /// The component's b's with an edge.
    pub b: u32,
    /// The largest cost of its edges (costs are non-negative).
    pub largest: f64,
    /// a x b is beyond the exact solve's limit.
    pub piled: bool,
}

/// The components of one assignment's nodes: a at index a, b at index n_a + b.
#[derive(Default)]
pub(super) struct Components {
    parent: Vec<u32>,
    /// Tree sizes while uniting, then whether a node has an edge.
    weight: Vec<u32>,
    root: Vec<u32>,
    /// Indexed by root; other entries stay empty.
    extent: Vec<Extent>,
    any_piled: bool,
}

impl Components {
    /// The components of `edges` over n_a + n_b nodes; a component whose a x b exceeds
    /// `max_cells` is marked piled.
    pub fn build(&mut self, n_a: usize, n_b: usize, edges: &[Edge], max_cells: usize) {
        let n = u32::try_from(n_a + n_b).expect("fewer than 2^32 boxes in an assignment");
        let base = n_a as u32;
        self.parent.clear();
        self.parent.extend(0..n);
        self.weight.clear();
        self.weight.resize(n as usize, 1);
        // Union by size keeps the trees shallow in one component spanning the scene.
        for e in edges {
            let (ra, rb) = (
                find(&mut self.parent, e.a),
                find(&mut self.parent, base + e.b),
            );
            if ra != rb {
                let (small, large) = if self.weight[ra as usize] < self.weight[rb as usize] {
                    (ra, rb)
                } else {
                    (rb, ra)
                };
                self.parent[small as usize] = large;
                self.weight[large as usize] += self.weight[small as usize];
            }
        }
        self.root.clear();
        for x in 0..n {
            let r = find(&mut self.parent, x);
            self.root.push(r);
        }
        self.extent.clear();
        self.extent.resize(n as usize, Extent::default());
        self.weight.fill(0);
        for e in edges {
            let r = self.root[e.a as usize] as usize;
            self.extent[r].largest = self.extent[r].largest.max(e.cost);
            self.weight[e.a as usize] = 1;
            self.weight[(base + e.b) as usize] = 1;
        }
        for (node, _) in self.weight.iter().enumerate().filter(|(_, &w)| w == 1) {
            let x = &mut self.extent[self.root[node] as usize];
            if node < n_a {
                x.a += 1;
            } else {
                x.b += 1;
            }
        }
        self.any_piled = false;
        for x in &mut self.extent {
            x.piled = (x.a as usize).saturating_mul(x.b as usize) > max_cells;
            self.any_piled |= x.piled;
        }
        trim(&mut self.parent);
        trim(&mut self.weight);
        trim(&mut self.root);
        trim(&mut self.extent);
    }

    /// The component of node `x` (a: its index; b: n_a + its index).
    pub fn of(&self, x: usize) -> Extent {
        self.extent[self.root[x] as usize]
    }

    /// The component of an edge.
    pub fn of_edge(&self, e: &Edge) -> Extent {
        self.of(e.ia())
    }

    /// Some component is piled.
    pub fn any_piled(&self) -> bool {
        self.any_piled
    }
}

/// The root of `x`, halving the path on the way.
fn find(p: &mut [u32], mut x: u32) -> u32 {
    while p[x as usize] != x {
        p[x as usize] = p[p[x as usize] as usize];
        x = p[x as usize];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_count_their_linked_nodes_and_largest_cost() {
        // a0-b0, a1-b0 and a2-b2; a3 and b1 have no edge.
        let edges = [
            Edge::new(0, 0, 0.5),
            Edge::new(1, 0, 2.0),
            Edge::new(2, 2, 1.0),
        ];
        let mut c = Components::default();
        c.build(4, 3, &edges, 1);
        let first = Extent {
            a: 2,
            b: 1,
            largest: 2.0,
            piled: true,
        };
        assert_eq!(c.of(0), first);
        assert_eq!(c.of(1), first);
        assert_eq!(c.of(4), first);
        let second = Extent {
            a: 1,
            b: 1,
            largest: 1.0,
            piled: false,
        };
        assert_eq!(c.of(2), second);
        assert_eq!(c.of_edge(&edges[2]), second);
        assert_eq!(c.of(3), Extent::default());
        assert_eq!(c.of(5), Extent::default());
        assert!(c.any_piled());
        // The same buffers, a second time, without a pile.
        c.build(4, 3, &edges, 2);
        assert!(!c.any_piled());
        assert!(!c.of(0).piled);
    }
}
