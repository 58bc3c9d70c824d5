//! The one loop of the single-frame benches over any data source: each frame's agents' boxes,
//! each row's boxes (an agent alone, a method through its pipeline, or a rule of the source's
//! or the bench's own), scored by the protocol the source names, in parallel and merged in frame
//! order so the figures do not depend on the threads. A data source is a [`Frames`]; a
//! protocol is a [`Protocol`] whose truth the source yields.

use crate::bench::fusers::Fusers;
use crate::bench::{in_order, FRAMES_PER_TASK};
use rayon::prelude::*;
use v2x_eval::protocol::{Merge, Protocol};
use v2x_protocol::{AgentKind, Detection};

/// One frame as a source yields it.
#[derive(Clone, Debug)]
pub struct BenchFrame<T> {
    /// The frame's position in the source.
    pub index: usize,
    /// Each agent's boxes, in agent order.
    pub agents: Vec<Vec<Detection>>,
    /// Each agent's kind, in agent order (registration's reference is the first roadside unit).
    pub kinds: Vec<AgentKind>,
    /// The time the methods fuse the frame at (µs).
    pub t_us: u64,
    /// What the boxes are scored against.
    pub truth: T,
}

/// A data source as the bench reads it, frame by frame.
pub trait Frames: Sync {
    /// What a frame's boxes are scored against: a protocol's truth, or a pair's.
    type Truth: Send + Sync;
    /// What the agents' frames cost on the air, added up over frames.
    type Cost: Merge + Default + Send;
    /// How many frames the source has.
    fn count(&self) -> usize;
    /// The frames each parallel part scores in order, the parts in frame order: runs of
    /// [`FRAMES_PER_TASK`] frames unless a step carries history over a scene.
    fn parts(&self) -> Vec<Vec<usize>> {
        runs(self.count())
    }
    /// Frame `i`, or `None` when it cannot be scored.
    fn frame(&self, i: usize) -> Option<BenchFrame<Self::Truth>>;
    /// What a frame's agents' boxes cost on the air.
    fn cost(&self, frame: &BenchFrame<Self::Truth>) -> Self::Cost;
}

/// `n` frames as runs of [`FRAMES_PER_TASK`], in order.
pub fn runs(n: usize) -> Vec<Vec<usize>> {
    let indices: Vec<usize> = (0..n).collect();
    indices
        .chunks(FRAMES_PER_TASK)
        .map(<[usize]>::to_vec)
        .collect()
}

/// A row's boxes from a rule over the frame, with the bench's fusers at hand.
pub type Rule<'a, T> = dyn Fn(&BenchFrame<T>, &mut Fusers) -> Vec<Detection> + Sync + 'a;

/// Where a row's boxes come from.
pub enum RowBoxes<'a, T> {
    /// One agent's, alone.
    Agent(usize),
    /// Method `m` of the bench's fusers, through its pipeline.
    Method(usize),
    /// A rule over the frame: a reference, a baseline, regional fusers.
    Rule(&'a Rule<'a, T>),
}

impl<T> RowBoxes<'_, T> {
    /// Each of `agents` agents alone, then each of `methods` methods.
    pub fn agents_then_methods(agents: usize, methods: usize) -> Vec<Self> {
        let agents = (0..agents).map(RowBoxes::Agent);
        agents.chain((0..methods).map(RowBoxes::Method)).collect()
    }
}

/// Each row's figures, what the frames cost and how many were scored.
#[derive(Clone, Debug)]
pub struct Totals<P, C> {
    /// Each row's protocol, in row order.
    pub rows: Vec<P>,
    /// The frames' cost on the air.
    pub cost: C,
    /// Frames scored.
    pub frames: usize,
}

impl<P: Merge, C: Merge> Totals<P, C> {
    fn absorb(mut self, other: Self) -> Self {
        for (a, b) in self.rows.iter_mut().zip(other.rows) {
            a.absorb(b);
        }
        self.cost.absorb(other.cost);
        self.frames += other.frames;
        self
    }
}

/// Scores every row over every frame of `source` by a fresh protocol each (`new`); each
/// parallel part runs a copy of `fusers` over its frames in order, and `tick` is called once
/// per frame scored.
pub fn score<F: Frames, P: Protocol<Truth = F::Truth>>(
    source: &F,
    rows: &[RowBoxes<'_, F::Truth>],
    fusers: &Fusers,
    new: impl Fn() -> P + Sync,
    tick: &(dyn Fn() + Sync),
) -> Totals<P, F::Cost> {
    let empty = || Totals {
        rows: rows.iter().map(|_| new()).collect(),
        cost: F::Cost::default(),
        frames: 0,
    };
    in_order(
        source.parts().into_par_iter(),
        |indices| {
            let mut part = empty();
            let mut fusers = fusers.clone();
            for frame in indices.into_iter().filter_map(|i| source.frame(i)) {
                fusers.set_kinds(frame.kinds.clone());
                for (row, p) in rows.iter().zip(&mut part.rows) {
                    match row {
                        RowBoxes::Agent(a) => p.add_frame(&frame.truth, &frame.agents[*a]),
                        RowBoxes::Method(m) => {
                            let fused = fusers.fuse(*m, frame.t_us, &frame.agents);
                            p.add_frame(&frame.truth, &fused);
                        }
                        RowBoxes::Rule(rule) => {
                            p.add_frame(&frame.truth, &rule(&frame, &mut fusers))
                        }
                    }
                }
                part.cost.absorb(source.cost(&frame));
                part.frames += 1;
                tick();
            }
            part
        },
        Totals::absorb,
    )
    .unwrap_or_else(empty)
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_eval::v2v4real_eval::V2v4realEval;
    use v2x_fuser::Method;
    use v2x_protocol::{Class, Uncertainty};

    fn car(x: f64, score: f64) -> Detection {
        Detection {
            class: Class::Car,
            center: [x, 5.0, 0.0],
            size: [4.5, 1.9, 1.6],
            score,
            std: Uncertainty::uniform(0.3, 0.1, 0.05),
            ..Detection::default()
        }
    }

    /// Boxes counted over frames.
    #[derive(Default)]
    struct Count(usize);

    impl Merge for Count {
        fn absorb(&mut self, other: Self) {
            self.0 += other.0;
        }
    }

    /// 70 frames of one car at x = i; agent 1 sees it 0.6 m off; frame 5 cannot be scored;
    /// `whole`: one part instead of runs.
    struct Toy {
        whole: bool,
    }

    impl Frames for Toy {
        type Truth = Vec<Detection>;
        type Cost = Count;

        fn count(&self) -> usize {
            70
        }

        fn parts(&self) -> Vec<Vec<usize>> {
            if self.whole {
                vec![(0..70).collect()]
            } else {
                runs(70)
            }
        }

        fn frame(&self, i: usize) -> Option<BenchFrame<Vec<Detection>>> {
            let x = i as f64;
            (i != 5).then(|| BenchFrame {
                index: i,
                agents: vec![vec![car(x, 0.9)], vec![car(x + 0.6, 0.8)]],
                kinds: vec![AgentKind::Vehicle; 2],
                t_us: i as u64 * 100_000,
                truth: vec![car(x, 1.0)],
            })
        }

        fn cost(&self, f: &BenchFrame<Vec<Detection>>) -> Count {
            Count(f.agents.iter().map(Vec::len).sum())
        }
    }

    #[test]
    fn every_row_is_scored_over_the_frames_a_source_yields_however_it_is_split() {
        let nothing = |_: &BenchFrame<Vec<Detection>>, _: &mut Fusers| Vec::new();
        let rows = [
            RowBoxes::Agent(0),
            RowBoxes::Agent(1),
            RowBoxes::Method(0),
            RowBoxes::Rule(&nothing),
        ];
        let fusers = Fusers::new(&[Method::default()], 2, None);
        let ticks = std::sync::atomic::AtomicUsize::new(0);
        let tick = || {
            ticks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        };
        let runs = score(
            &Toy { whole: false },
            &rows,
            &fusers,
            V2v4realEval::new,
            &tick,
        );
        let whole = score(
            &Toy { whole: true },
            &rows,
            &fusers,
            V2v4realEval::new,
            &|| (),
        );
        assert_eq!((runs.frames, runs.cost.0), (69, 138));
        assert_eq!(ticks.into_inner(), 69);
        let ap = |t: &Totals<V2v4realEval, Count>, row: usize| t.rows[row].summary().ap_bev;
        for row in 0..rows.len() {
            assert_eq!(ap(&runs, row), ap(&whole, row), "row {row}");
        }
        assert_eq!(ap(&runs, 0)["0.70"], 1.0);
        // 0.6 m off on a 4.5 m car: BEV IoU 0.77, found at 0.7; fused between the two, too.
        assert_eq!(ap(&runs, 1)["0.70"], 1.0);
        assert_eq!(ap(&runs, 2)["0.70"], 1.0);
        assert_eq!(runs.rows[3].summary().predictions, 0);
        assert_eq!(runs.rows[2].summary().predictions, 69);
    }
}
