//! Time alignment of agents' frames (DESIGN §8), sans-IO: no clock, no network. The caller
//! passes "now" (the fuser's own clock, microseconds) and the set of live agents.
//!
//! A window is anchored at the capture time of the first frame that opens it and takes the frames
//! whose capture time lies within delta t / 2 of the anchor, one per agent. It closes when every
//! live agent has contributed, or when its deadline (first arrival + max wait, on the fuser's
//! clock) passes; closing a window first closes every older one, so windows come out in capture
//! order. A frame for a closed window is late; a frame already seen (same agent, sequence number
//! and capture time) or a second frame of one agent in one window is a duplicate. Both are
//! counted and dropped by the caller, never fused twice.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use v2x_protocol::Frame;

/// What happened to an inserted frame.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Joined an open window.
    Accepted,
    /// Its window was already closed.
    Late,
    /// Already seen, or its agent already has a frame in that window.
    Duplicate,
}

/// A window ready to fuse.
#[derive(Clone, Debug, PartialEq)]
pub struct Closed {
    /// Capture time of the frame that opened it (us).
    pub anchor_us: u64,
    /// One frame per agent, by agent name.
    pub frames: BTreeMap<String, Frame>,
    /// Whether every live agent contributed.
    pub complete: bool,
    /// When its first frame arrived (fuser clock, us).
    pub first_arrival_us: u64,
}

#[derive(Debug)]
struct Open {
    anchor_us: u64,
    first_arrival_us: u64,
    frames: BTreeMap<String, Frame>,
}

/// The window state machine.
#[derive(Debug)]
pub struct Windows {
    delta_us: u64,
    max_wait_us: u64,
    open: Vec<Open>,
    last_closed: Option<u64>,
    recent: HashMap<String, VecDeque<(u32, u64)>>,
}

const RECENT: usize = 64;

impl Windows {
    /// Windows of `delta_us` that wait at most `max_wait_us` after their first frame.
    pub fn new(delta_us: u64, max_wait_us: u64) -> Self {
        Windows {
            delta_us: delta_us.max(1),
            max_wait_us,
            open: Vec::new(),
            last_closed: None,
            recent: HashMap::new(),
        }
    }

    /// Forgets an agent's recent sequence numbers (it restarted and counts from 0 again).
    pub fn reset_agent(&mut self, agent: &str) {
        self.recent.remove(agent);
    }

    /// Number of open windows.
    pub fn open_windows(&self) -> usize {
        self.open.len()
    }

    /// Offers a frame that arrived at `now_us`.
    pub fn insert(&mut self, frame: Frame, now_us: u64) -> Verdict {
        let key = (frame.seq, frame.capture_us);
        let recent = self.recent.entry(frame.agent.clone()).or_default();
        if recent.contains(&key) {
            return Verdict::Duplicate;
        }
        recent.push_back(key);
        if recent.len() > RECENT {
            recent.pop_front();
        }
        let half = self.delta_us / 2;
        let t = frame.capture_us;
        if let Some(c) = self.last_closed {
            if t < c.saturating_add(half) {
                return Verdict::Late;
            }
        }
        let nearest = self
            .open
            .iter_mut()
            .filter(|w| w.anchor_us.abs_diff(t) < half.max(1))
            .min_by_key(|w| w.anchor_us.abs_diff(t));
        match nearest {
            Some(w) => {
                if w.frames.contains_key(&frame.agent) {
                    return Verdict::Duplicate;
                }
                w.frames.insert(frame.agent.clone(), frame);
            }
            None => {
                let pos = self.open.partition_point(|w| w.anchor_us <= t);
                let mut frames = BTreeMap::new();
                frames.insert(frame.agent.clone(), frame);
                self.open.insert(
                    pos,
                    Open {
                        anchor_us: t,
                        first_arrival_us: now_us,
                        frames,
                    },
                );
            }
        }
        Verdict::Accepted
    }

    /// When the next deadline falls (fuser clock, us), if any window is open.
    pub fn next_deadline(&self) -> Option<u64> {
        self.open
            .iter()
            .map(|w| w.first_arrival_us.saturating_add(self.max_wait_us))
            .min()
    }

    /// Closes what is ready: the newest window that is complete (every agent of `live` in it) or
    /// past its deadline, and every window older than it.
    pub fn poll(&mut self, now_us: u64, live: &BTreeSet<String>) -> Vec<Closed> {
        let complete = |w: &Open| !live.is_empty() && live.iter().all(|a| w.frames.contains_key(a));
        let ready = self.open.iter().rposition(|w| {
            complete(w) || now_us >= w.first_arrival_us.saturating_add(self.max_wait_us)
        });
        let Some(last) = ready else {
            return Vec::new();
        };
        let closed: Vec<Closed> = self
            .open
            .drain(..=last)
            .map(|w| Closed {
                complete: complete(&w),
                anchor_us: w.anchor_us,
                frames: w.frames,
                first_arrival_us: w.first_arrival_us,
            })
            .collect();
        self.last_closed = closed.last().map(|c| c.anchor_us);
        closed
    }

    /// Closes every open window (at shutdown).
    pub fn flush(&mut self, live: &BTreeSet<String>) -> Vec<Closed> {
        self.poll(u64::MAX, live)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::AgentKind;

    fn f(agent: &str, seq: u32, t_ms: u64) -> Frame {
        Frame {
            agent: agent.into(),
            kind: AgentKind::Vehicle,
            seq,
            capture_us: t_ms * 1000,
            origin: [0.0; 3],
            detections: vec![],
        }
    }

    fn live(names: &[&str]) -> BTreeSet<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    const MS: u64 = 1000;

    #[test]
    fn closes_when_every_live_agent_contributed() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        assert_eq!(w.insert(f("a", 0, 1000), 0), Verdict::Accepted);
        assert!(w.poll(1, &l).is_empty());
        // b's clock is 20 ms off: same window
        assert_eq!(w.insert(f("b", 0, 1020), 5 * MS), Verdict::Accepted);
        let c = w.poll(5 * MS, &l);
        assert_eq!(c.len(), 1);
        assert!(c[0].complete);
        assert_eq!(c[0].anchor_us, 1000 * MS);
        assert_eq!(c[0].frames.len(), 2);
    }

    #[test]
    fn deadline_closes_an_incomplete_window() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        w.insert(f("a", 0, 1000), 0);
        assert_eq!(w.next_deadline(), Some(150 * MS));
        assert!(w.poll(149 * MS, &l).is_empty());
        let c = w.poll(150 * MS, &l);
        assert_eq!(c.len(), 1);
        assert!(!c[0].complete);
        // b's frame comes after the window closed: late, never fused
        assert_eq!(w.insert(f("b", 0, 1010), 160 * MS), Verdict::Late);
        assert!(w.flush(&l).is_empty());
    }

    #[test]
    fn duplicates_and_two_frames_of_one_agent() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        assert_eq!(w.insert(f("a", 0, 1000), 0), Verdict::Accepted);
        assert_eq!(w.insert(f("a", 0, 1000), 1), Verdict::Duplicate);
        assert_eq!(
            w.insert(f("a", 1, 1030), 2),
            Verdict::Duplicate,
            "second frame in the same window"
        );
        // after a restart the agent counts from 0 again at a new capture time: fine
        assert_eq!(w.insert(f("a", 0, 1100), 3), Verdict::Accepted);
    }

    #[test]
    fn out_of_order_frames_join_their_window_and_windows_close_in_order() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        w.insert(f("a", 1, 1100), 0);
        w.insert(f("a", 0, 1000), 1); // arrives after a newer one
        w.insert(f("b", 0, 1000), 2);
        let c = w.poll(3, &l);
        assert_eq!(c.len(), 1, "the older window is complete; the newer waits");
        assert_eq!(c[0].anchor_us, 1000 * MS);
        w.insert(f("b", 1, 1101), 4);
        // completing the newest closes it (and anything older)
        let c = w.poll(5, &l);
        assert_eq!(
            c.iter().map(|c| c.anchor_us).collect::<Vec<_>>(),
            vec![1100 * MS]
        );
    }

    #[test]
    fn a_complete_newer_window_closes_older_incomplete_ones_first() {
        let mut w = Windows::new(100 * MS, 1000 * MS);
        let l = live(&["a", "b"]);
        w.insert(f("a", 0, 1000), 0); // b's frame for 1000 was lost
        w.insert(f("a", 1, 1100), 1);
        w.insert(f("b", 1, 1100), 2);
        let c = w.poll(3, &l);
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].anchor_us, c[0].complete), (1000 * MS, false));
        assert_eq!((c[1].anchor_us, c[1].complete), (1100 * MS, true));
        assert_eq!(w.insert(f("b", 0, 1000), 4), Verdict::Late);
    }

    #[test]
    fn with_no_live_agent_only_deadlines_close() {
        let mut w = Windows::new(100 * MS, 50 * MS);
        w.insert(f("a", 0, 0), 0);
        assert!(w.poll(10, &BTreeSet::new()).is_empty());
        assert_eq!(w.poll(50 * MS, &BTreeSet::new()).len(), 1);
    }
}
