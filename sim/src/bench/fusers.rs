//! The methods of a bench, each run as the fuser runs a window: through its pipeline
//! (`v2x_fuser::pipeline`), so that a per-window step added there reaches every bench.

use v2x_fuser::pipeline::{Pipeline, Reference, Steps};
use v2x_fuser::time::align::AlignParams;
use v2x_fuser::time::window::Closed;
use v2x_fuser::Method;
use v2x_protocol::{AgentKind, Detection, Frame};

/// One pipeline per method over the same agents, each with its own history.
#[derive(Clone, Debug)]
pub struct Fusers {
    pipelines: Vec<Pipeline>,
    names: Vec<String>,
    kinds: Vec<AgentKind>,
}

impl Fusers {
    /// The `methods` over `agents` agents named agent1, agent2..., every one a vehicle until
    /// [`Fusers::set_kinds`]; with `align`, each registers the agents to the first
    /// infrastructure agent (else the first) before fusing.
    pub fn new(methods: &[Method], agents: usize, align: Option<AlignParams>) -> Fusers {
        Fusers::with_steps(methods, agents, |method| Steps {
            align,
            ..Steps::method(method)
        })
    }

    /// The `methods` over `agents` agents, each method's pipeline running `steps(method)`.
    pub fn with_steps(
        methods: &[Method],
        agents: usize,
        steps: impl Fn(Method) -> Steps,
    ) -> Fusers {
        Fusers::of_steps(methods.iter().map(|&m| steps(m)), agents)
    }

    /// One pipeline per element of `steps`, in order, over `agents` agents.
    pub fn of_steps(steps: impl IntoIterator<Item = Steps>, agents: usize) -> Fusers {
        let pipelines = steps
            .into_iter()
            .map(|steps| Pipeline::new(steps, Reference::Infrastructure, None))
            .collect();
        Fusers {
            pipelines,
            names: (1..=agents).map(|a| format!("agent{a}")).collect(),
            kinds: vec![AgentKind::Vehicle; agents],
        }
    }

    /// Each agent's kind, in agent order.
    pub fn set_kinds(&mut self, kinds: Vec<AgentKind>) {
        self.kinds = kinds;
    }

    /// Method `m`'s fused boxes of one frame of the agents' boxes, captured at `t_us`.
    pub fn fuse(&mut self, m: usize, t_us: u64, lists: &[Vec<Detection>]) -> Vec<Detection> {
        self.pipelines[m].fuse_frame(Some(t_us), &self.names, &self.kinds, lists)
    }

    /// Method `m`'s fused boxes of one window whose agents captured their boxes at different
    /// instants (`captures`, in agent order): the whole pipeline, motion compensation to the
    /// latest capture included when its steps have it. The window orders its agents by name,
    /// which is agent order up to nine agents.
    pub fn fuse_window(
        &mut self,
        m: usize,
        captures: &[u64],
        lists: &[Vec<Detection>],
    ) -> Vec<Detection> {
        let closed = Closed::of((0..lists.len()).map(|a| Frame {
            agent: self.names[a].clone(),
            kind: self.kinds[a],
            seq: 0,
            capture_us: captures[a],
            origin: [0.0; 3],
            detections: lists[a].clone(),
        }));
        let pipeline = &mut self.pipelines[m];
        let prepared = pipeline.prepare(closed);
        pipeline
            .steps()
            .fuse_boxes(&prepared.lists, prepared.receiver)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::{Class, Uncertainty};

    fn car(x: f64, y: f64, pos_std: f64) -> Detection {
        Detection {
            class: Class::Car,
            center: [x, y, 0.0],
            size: [4.5, 1.9, 1.6],
            score: 0.9,
            std: Uncertainty {
                pos: [pos_std, pos_std, 0.2],
                size: [0.2; 3],
                yaw: 0.1,
            },
            ..Detection::default()
        }
    }

    #[test]
    fn each_method_fuses_as_its_pipeline_and_registers_with_its_own_history() {
        let methods: Vec<Method> = ["csba-wls+", "nms-3d"]
            .iter()
            .map(|m| m.parse().unwrap())
            .collect();
        let lists = vec![vec![car(10.0, 0.0, 0.5)], vec![car(10.4, 0.2, 0.5)]];
        let mut plain = Fusers::new(&methods, 2, None);
        for (m, method) in methods.iter().enumerate() {
            assert_eq!(plain.fuse(m, 0, &lists), method.fuse(&lists));
        }
        // Registered: the second agent's boxes are moved onto the first's once the estimate
        // is significant, so the fused box changes over the windows.
        let mut aligned = Fusers::new(&methods, 2, Some(AlignParams::default()));
        aligned.set_kinds(vec![AgentKind::Infrastructure, AgentKind::Vehicle]);
        let first = aligned.fuse(0, 0, &lists);
        assert_eq!(first, methods[0].fuse(&lists));
        // Nine cars on a grid, the second agent's boxes 1.2 m off along x.
        let many: Vec<Vec<Detection>> = (0..9)
            .map(|k| {
                let (x, y) = (8.0 * (k % 3) as f64, 8.0 * (k / 3) as f64);
                vec![car(x, y, 0.3), car(x + 1.2, y, 0.3)]
            })
            .collect();
        let (a, b): (Vec<_>, Vec<_>) = many
            .iter()
            .map(|l| (vec![l[0].clone()], vec![l[1].clone()]))
            .unzip();
        let window = vec![a.concat(), b.concat()];
        let mut last = Vec::new();
        for k in 0..20u64 {
            last = aligned.fuse(0, k * 100_000, &window);
        }
        // Fused where the reference sees each car, not halfway to the shifted boxes.
        let plain_x = methods[0].fuse(&window)[0].center[0];
        assert!((plain_x - 0.6).abs() < 1e-9, "{plain_x}");
        assert!(last[0].center[0].abs() < 0.1, "{:?}", last[0].center);
    }
}
