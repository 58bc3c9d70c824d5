//! Properties checked on arbitrary input, shared by the fuzz target `window` (`fuzz/`) and by the
//! regression test that replays its corpus and every input that once failed.

use crate::time::window::{Closed, Verdict, Windows};
use std::collections::{BTreeSet, HashSet};
use v2x_protocol::{AgentKind, Frame};

/// A frame's identity: agent, sequence number, capture time.
type Key = (String, u32, u64);

const AGENTS: [&str; 6] = ["a", "b", "c", "d", "e", "f"];

/// Drives the window state machine with the events `data` spells, four bytes each, and checks
/// its invariants: no frame is fused twice, every fused frame was admitted and lies within half
/// a window of its anchor, windows close in capture order, and the state stays bounded.
///
/// Event `[op, a, b, c]`: the fuser's clock first advances by `c % 64` ms; then `op % 4` is
/// 0 or 1: a frame of agent `a % 6` with sequence number `a / 8`, captured `b - 128` x 5 ms
/// from now; 2: a poll awaiting the agents of bit mask `b`; 3: agent `a % 6` is reset (odd `b`)
/// or forgotten (even `b`).
pub fn window_events(data: &[u8]) {
    let mut w = Windows::new(100_000, 150_000);
    let mut now: u64 = 10_000_000;
    let mut admitted: HashSet<Key> = HashSet::new();
    let mut fused: HashSet<Key> = HashSet::new();
    let mut last_anchor: Option<u64> = None;
    let mut check = |closed: Vec<Closed>, w: &Windows, admitted: &HashSet<Key>| {
        for c in closed {
            if let Some(prev) = last_anchor {
                assert!(c.anchor_us > prev, "windows close in capture order");
            }
            last_anchor = Some(c.anchor_us);
            assert!(!c.frames.is_empty());
            for (agent, f) in &c.frames {
                assert_eq!(agent, &f.agent);
                let key = (f.agent.clone(), f.seq, f.capture_us);
                assert!(admitted.contains(&key), "a fused frame was admitted");
                assert!(fused.insert(key), "no frame is fused twice");
                assert!(f.capture_us.abs_diff(c.anchor_us) < w.half_us());
            }
        }
        assert!(w.open_windows() <= 64, "{} open windows", w.open_windows());
        assert!(w.open_frames() <= AGENTS.len() * w.open_windows());
        assert!(w.remembered_agents() <= AGENTS.len());
    };
    for ev in data.chunks_exact(4) {
        let (op, a, b, c) = (ev[0], ev[1], ev[2], ev[3]);
        now += (c % 64) as u64 * 1000;
        let agent = AGENTS[(a % 6) as usize];
        match op % 4 {
            0 | 1 => {
                let capture = (now as i64 + (b as i64 - 128) * 5_000) as u64;
                let frame = Frame {
                    agent: agent.into(),
                    kind: AgentKind::Vehicle,
                    seq: (a / 8) as u32,
                    capture_us: capture,
                    origin: [0.0; 3],
                    detections: Vec::new(),
                };
                let key = (agent.to_string(), frame.seq, capture);
                match w.insert(frame, now) {
                    Verdict::Accepted | Verdict::Replaced => {
                        admitted.insert(key);
                    }
                    Verdict::Duplicate | Verdict::Late | Verdict::Superseded => {}
                }
            }
            2 => {
                let awaited: BTreeSet<String> = AGENTS
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| b & (1 << i) != 0)
                    .map(|(_, n)| n.to_string())
                    .collect();
                let closed = w.poll(now, |_| awaited.clone());
                check(closed, &w, &admitted);
            }
            _ if b % 2 == 1 => w.reset_agent(agent),
            _ => w.forget_agent(agent),
        }
    }
    let all: BTreeSet<String> = AGENTS.iter().map(|s| s.to_string()).collect();
    let closed = w.flush(|_| all.clone());
    check(closed, &w, &admitted);
    assert_eq!(w.open_windows(), 0);
}
