//! The area of interest: boxes whose centre lies outside are dropped at admission, and an agent
//! brings at most its budget of boxes. The area is given, or learned from where most agents are.

use super::{Ingest, Note};
use v2x_protocol::{Frame, InvalidValue};

/// Where the fuser stands: boxes whose centre lies outside are dropped at admission.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Area {
    /// A disc of the map frame's xy plane, given in the configuration.
    Given {
        /// Its centre (x, y), m.
        center: [f64; 2],
        /// Its radius, m.
        radius_m: f64,
    },
    /// A disc of this radius around where the agents are: each agent's position is the median
    /// centre of its first boxes, and the area is centred on the positions of the largest group
    /// of agents within the radius of one another (the earliest agent's on a tie), so that a
    /// minority of agents far away cannot move it.
    Learned {
        /// Its radius, m.
        radius_m: f64,
    },
}

impl Area {
    /// The default: learned, 10 km across every way from where the agents are.
    pub const DEFAULT: Area = Area::Learned { radius_m: 10_000.0 };

    /// The radius, m.
    pub fn radius_m(&self) -> f64 {
        match *self {
            Area::Given { radius_m, .. } | Area::Learned { radius_m } => radius_m,
        }
    }

    /// Parses `X,Y,RADIUS` (m, map frame) into a given area.
    pub fn parse(s: &str) -> Result<Area, InvalidValue> {
        let bad = || InvalidValue::new("area", "X,Y,RADIUS in metres", s);
        let v: Vec<f64> = s
            .split(',')
            .map(|p| p.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad())?;
        let [x, y, r] = v[..] else {
            return Err(bad());
        };
        let a = Area::Given {
            center: [x, y],
            radius_m: r,
        };
        a.validate().map(|()| a)
    }

    /// Checks the values: a finite centre and a finite radius > 0.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        let r = self.radius_m();
        if !(r.is_finite() && r > 0.0) {
            return Err(InvalidValue::new("the area's radius", "finite and > 0", r));
        }
        if let Area::Given { center, .. } = self {
            if !center
                .iter()
                .all(|c| v2x_protocol::limits::coord_in_range(*c))
            {
                let got = format!("{center:?}");
                return Err(InvalidValue::new(
                    "the area's centre",
                    "within the map's range",
                    got,
                ));
            }
        }
        Ok(())
    }
}

impl Ingest {
    /// Keeps the boxes of an admitted frame within the area of interest, then within the
    /// agent's budget (the highest scores, in their order), counting what it drops.
    pub(super) fn confine(&mut self, agent: &str, frame: &mut Frame) {
        if let Some(st) = self.agents.get_mut(agent) {
            if st.position.is_none() && !frame.detections.is_empty() {
                st.position = Some(median_xy(&frame.detections));
                if matches!(self.cfg.area, Area::Learned { .. }) {
                    self.center = self.learned_center();
                }
            }
        }
        let (Some(c), r) = (self.center, self.cfg.area.radius_m()) else {
            return;
        };
        let before = frame.detections.len();
        frame
            .detections
            .retain(|d| (d.center[0] - c[0]).hypot(d.center[1] - c[1]) <= r);
        let outside = before - frame.detections.len();
        let budget = self.cfg.max_objects;
        let over = frame.detections.len().saturating_sub(budget);
        if over > 0 {
            let mut order: Vec<usize> = (0..frame.detections.len()).collect();
            order.sort_by(|&a, &b| {
                let (da, db) = (&frame.detections[a], &frame.detections[b]);
                db.score.total_cmp(&da.score).then(a.cmp(&b))
            });
            let mut keep = vec![false; order.len()];
            for &i in &order[..budget] {
                keep[i] = true;
            }
            let mut i = 0;
            frame.detections.retain(|_| {
                i += 1;
                keep[i - 1]
            });
        }
        let Some(st) = self.agents.get_mut(agent) else {
            return;
        };
        st.stats.outside += outside as u64;
        st.stats.over_budget += over as u64;
        if outside > 0 {
            let agent = agent.to_string();
            self.note(
                Note::Outside {
                    agent,
                    dropped: outside,
                },
                outside as u64,
            );
        }
        if over > 0 {
            let agent = agent.to_string();
            self.note(
                Note::OverBudget {
                    agent,
                    dropped: over,
                },
                over as u64,
            );
        }
    }

    /// The learned area's centre: the median position of the largest group of agents within the
    /// radius of one agent (the earliest heard on a tie).
    pub(super) fn learned_center(&self) -> Option<[f64; 2]> {
        let r = self.cfg.area.radius_m();
        let mut placed: Vec<(u64, [f64; 2])> = self
            .agents
            .values()
            .filter_map(|s| s.position.map(|p| (s.first_heard_us, p)))
            .collect();
        placed.sort_by_key(|(t, _)| *t);
        let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) <= r;
        let best = placed
            .iter()
            .map(|(_, p)| placed.iter().filter(|(_, q)| near(*p, *q)).count())
            .enumerate()
            // the most neighbours; of equals, the first (earliest heard)
            .max_by(|(i, a), (j, b)| a.cmp(b).then(j.cmp(i)))
            .map(|(i, _)| placed[i].1)?;
        let group: Vec<[f64; 2]> = placed
            .iter()
            .map(|(_, q)| *q)
            .filter(|q| near(best, *q))
            .collect();
        Some([0, 1].map(|k| {
            let mut v: Vec<f64> = group.iter().map(|p| p[k]).collect();
            v.sort_by(f64::total_cmp);
            v[(v.len() - 1) / 2]
        }))
    }

    /// The area of interest's centre, once given or learned.
    pub fn area_center(&self) -> Option<[f64; 2]> {
        self.center
    }
}

/// The component-wise median of the boxes' centres (x, y); the boxes must not be empty.
pub(super) fn median_xy(dets: &[v2x_protocol::Detection]) -> [f64; 2] {
    [0, 1].map(|k| {
        let mut v: Vec<f64> = dets.iter().map(|d| d.center[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    })
}
