//! Prints the payload-size table of docs/guide.md ("Wire format and bandwidth"): bytes per frame
//! and per object for this wire format, postcard of plain f32 fields, and JSON, on urban-like
//! frames with uniform stds; then the same frames with a velocity on every box (what velocities
//! cost on the wire).
//!
//! Run: `cargo run --release -p v2x-protocol --example wire_sizes`

use serde::Serialize;
use v2x_protocol::nuscenes_json::stable_id;
use v2x_protocol::wire::encode;
use v2x_protocol::{wrap_angle, AgentKind, Class, Detection, Frame, Uncertainty, Velocity};

/// A deterministic stream of uniform numbers in [0, 1) (xorshift64).
fn uniform(mut state: u64) -> impl FnMut() -> f64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A deterministic urban-like frame: objects of mixed classes within 70 m of the agent, sizes
/// within +-15% of typical, ground-truth ids as the simulation gives them (hashes of instance
/// tokens).
fn urban_frame(n: usize) -> Frame {
    let mut next = uniform(0x9E37_79B9_7F4A_7C15);
    let mix = v2x_protocol::fixtures::URBAN_MIX;
    let detections = (0..n)
        .map(|i| {
            let class = mix[i % mix.len()];
            let r = 70.0 * next().sqrt();
            let a = next() * std::f64::consts::TAU;
            Detection {
                class,
                center: [
                    5123.4 + r * a.cos(),
                    -812.7 + r * a.sin(),
                    31.2 + 0.5 * next(),
                ],
                size: class.typical_size().map(|s| s * (0.85 + 0.3 * next())),
                yaw: wrap_angle(next() * 7.0),
                score: 0.5 + 0.5 * next(),
                std: Uncertainty::uniform(0.5, 0.1, 5f64.to_radians()),
                pos_cov: None,
                velocity: None,
                id: stable_id(&format!("instance-{i}")),
            }
        })
        .collect();
    Frame {
        agent: "veh1".into(),
        kind: AgentKind::Vehicle,
        seq: 1234,
        capture_us: 1_700_000_000_123_456,
        origin: [5123.4, -812.7, 31.2],
        detections,
    }
}

/// The frame with urban velocities: half the vehicles parked or waiting (near 0), the others at
/// 5-15 m/s along their heading; pedestrians and cyclists at walking and riding speeds; barriers
/// and cones still; every velocity with the noise of a good detector (0.25 m/s std).
fn with_velocities(mut f: Frame) -> Frame {
    let mut next = uniform(0x2545_F491_4F6C_DD1D);
    for d in &mut f.detections {
        let speed = match d.class {
            Class::Barrier | Class::TrafficCone => 0.0,
            Class::Pedestrian => 1.4 * next(),
            Class::Bicycle => 5.0 * next(),
            _ if next() < 0.5 => 0.0,
            _ => 5.0 + 10.0 * next(),
        };
        let noise = 0.25 * (next() - 0.5) * 3.4;
        d.velocity = Some(Velocity {
            v: [speed * d.yaw.cos() + noise, speed * d.yaw.sin() - noise],
            std: [0.25, 0.25],
        });
    }
    f
}

fn main() {
    println!("| objects | this format: bytes/frame | bytes/object | postcard f32: bytes/frame | bytes/object | JSON: bytes/frame | bytes/object |");
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    for n in [1usize, 25, 75, 250] {
        let f = urban_frame(n);
        let w = encode(&f).expect("frame encodes").len();
        let p = encode_plain_f32(&f).len();
        let j = encode_json(&f).len();
        let per = |b: usize| b as f64 / n as f64;
        println!(
            "| {n} | {w} | {:.1} | {p} | {:.1} | {j} | {:.1} |",
            per(w),
            per(p),
            per(j)
        );
    }
    println!();
    println!("| objects | without ids (a detector's own boxes): bytes/frame | bytes/object | saved per object |");
    println!("|---:|---:|---:|---:|");
    for n in [1usize, 25, 75, 250] {
        let with = encode(&urban_frame(n)).expect("frame encodes").len();
        let mut f = urban_frame(n);
        for d in &mut f.detections {
            d.id = v2x_protocol::NO_ID;
        }
        let w = encode(&f).expect("frame encodes").len();
        println!(
            "| {n} | {w} | {:.1} | {:.2} |",
            w as f64 / n as f64,
            (with as f64 - w as f64) / n as f64
        );
    }
    println!();
    println!("| objects | with velocities: bytes/frame | bytes/object | added per object |");
    println!("|---:|---:|---:|---:|");
    for n in [1usize, 25, 75, 250] {
        let plain = encode(&urban_frame(n)).expect("frame encodes").len();
        let w = encode(&with_velocities(urban_frame(n)))
            .expect("frame encodes")
            .len();
        println!(
            "| {n} | {w} | {:.1} | {:+.2} |",
            w as f64 / n as f64,
            (w as f64 - plain as f64) / n as f64
        );
    }
}

/// Encodes a frame as postcard of plain `f32` fields (no quantization), for size comparisons.
pub fn encode_plain_f32(frame: &Frame) -> Vec<u8> {
    #[derive(Serialize)]
    struct PlainObject {
        class: u8,
        center: [f32; 3],
        size: [f32; 3],
        yaw: f32,
        score: f32,
        std: [f32; 7],
        id: u32,
    }
    #[derive(Serialize)]
    struct PlainFrame<'a> {
        agent: &'a str,
        kind: u8,
        seq: u32,
        capture_us: u64,
        origin: [f32; 3],
        objects: Vec<PlainObject>,
    }
    let pf = PlainFrame {
        agent: &frame.agent,
        kind: frame.kind as u8,
        seq: frame.seq,
        capture_us: frame.capture_us,
        origin: frame.origin.map(|v| v as f32),
        objects: frame
            .detections
            .iter()
            .map(|d| PlainObject {
                class: d.class.code(),
                center: d.center.map(|v| v as f32),
                size: d.size.map(|v| v as f32),
                yaw: d.yaw as f32,
                score: d.score as f32,
                std: d.std.as_array().map(|v| v as f32),
                id: d.id,
            })
            .collect(),
    };
    postcard::to_stdvec(&pf).expect("postcard serialization into a Vec cannot fail")
}

/// A frame as JSON (serde's natural form).
pub fn encode_json(frame: &Frame) -> Vec<u8> {
    serde_json::to_vec(frame).expect("a frame always serializes to JSON")
}
