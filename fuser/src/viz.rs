//! What a run looks like, for Foxglove: boxes as `foxglove.SceneUpdate` messages (a cube per box
//! coloured by its source, a text with id and class (and, for fused boxes, the agents each came
//! from), an arrow for its velocity), written to an
//! MCAP file and/or served live over the Foxglove WebSocket protocol, each message stamped with
//! its capture time. Topics: `/agents/NAME` (what each agent sent), `/fused`, `/ground_truth`
//! (simulated runs), and `/stats` (one JSON message per fused window).

use foxglove::schemas::{
    ArrowPrimitive, Color, CubePrimitive, Pose, Quaternion, SceneEntity, SceneUpdate,
    TextPrimitive, Timestamp, Vector3,
};
use foxglove::{Channel, Context, McapWriterHandle, PartialMetadata, RawChannel, Schema};
use std::collections::HashMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::{Arc, Mutex};
use v2x_protocol::{Detection, InvalidValue, Provenance};

/// The colour of fused boxes.
pub const FUSED: [f64; 3] = [0.1, 0.8, 0.2];
/// The colour of ground truth.
pub const GROUND_TRUTH: [f64; 3] = [0.85, 0.85, 0.85];
const AGENT_COLOURS: [[f64; 3]; 6] = [
    [0.2, 0.5, 1.0],
    [1.0, 0.45, 0.1],
    [0.8, 0.2, 0.8],
    [1.0, 0.85, 0.1],
    [0.1, 0.8, 0.9],
    [0.9, 0.2, 0.3],
];

/// An agent's colour, the same in every run (from its name).
pub fn agent_colour(name: &str) -> [f64; 3] {
    let h = name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    });
    AGENT_COLOURS[(h % AGENT_COLOURS.len() as u64) as usize]
}

fn timestamp(t_us: u64) -> Timestamp {
    let sec = (t_us / 1_000_000).min(u32::MAX as u64) as u32;
    Timestamp::new(sec, (t_us % 1_000_000) as u32 * 1000)
}

fn yaw_quaternion(yaw: f64) -> Quaternion {
    let (s, c) = (yaw / 2.0).sin_cos();
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: s,
        w: c,
    }
}

/// One SceneUpdate of boxes from `source` at `t_us`: per box an entity `SOURCE/i` with its cube,
/// a label `id class`, and an arrow along its velocity (length: one second of travel).
pub fn scene(source: &str, t_us: u64, boxes: &[Detection], rgb: [f64; 3]) -> SceneUpdate {
    scene_with_sources(source, t_us, boxes, rgb, None)
}

/// [`scene`] for fused boxes: each label also names the agents the box came from
/// (`id class from a+b`).
pub fn scene_with_sources(
    source: &str,
    t_us: u64,
    boxes: &[Detection],
    rgb: [f64; 3],
    provenance: Option<&Provenance>,
) -> SceneUpdate {
    let colour = |a: f64| Color {
        r: rgb[0],
        g: rgb[1],
        b: rgb[2],
        a,
    };
    let entities = boxes
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let [x, y, z] = d.center;
            let pose = Pose {
                position: Some(Vector3 { x, y, z }),
                orientation: Some(yaw_quaternion(d.yaw)),
            };
            let arrows = velocity_arrow(d, colour(1.0)).into_iter().collect();
            SceneEntity {
                timestamp: Some(timestamp(t_us)),
                frame_id: "map".into(),
                id: format!("{source}/{i}"),
                lifetime: None,
                frame_locked: false,
                cubes: vec![CubePrimitive {
                    pose: Some(pose),
                    size: Some(Vector3 {
                        x: d.size[0],
                        y: d.size[1],
                        z: d.size[2],
                    }),
                    color: Some(colour(0.4)),
                }],
                texts: vec![TextPrimitive {
                    pose: Some(Pose {
                        position: Some(Vector3 {
                            x,
                            y,
                            z: z + d.size[2] / 2.0 + 0.5,
                        }),
                        orientation: Some(yaw_quaternion(0.0)),
                    }),
                    billboard: true,
                    font_size: 12.0,
                    scale_invariant: true,
                    color: Some(colour(1.0)),
                    text: match provenance.and_then(|p| Some((p, p.sources.get(i)?))) {
                        Some((p, set)) => format!(
                            "{} {} from {}",
                            d.id,
                            d.class,
                            p.names(set).collect::<Vec<_>>().join("+")
                        ),
                        None => format!("{} {}", d.id, d.class),
                    },
                }],
                arrows,
                ..Default::default()
            }
        })
        .collect();
    SceneUpdate {
        // Each message replaces the source's previous boxes.
        deletions: vec![foxglove::schemas::SceneEntityDeletion {
            timestamp: Some(timestamp(t_us)),
            r#type: foxglove::schemas::scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities,
    }
}

/// An arrow for a box's velocity, from its centre, when it moves faster than 5 cm/s.
fn velocity_arrow(d: &Detection, color: Color) -> Option<ArrowPrimitive> {
    let [x, y, z] = d.center;
    d.velocity
        .filter(|v| v.v[0].hypot(v.v[1]) > 0.05)
        .map(|v| ArrowPrimitive {
            pose: Some(Pose {
                position: Some(Vector3 { x, y, z }),
                orientation: Some(yaw_quaternion(v.v[1].atan2(v.v[0]))),
            }),
            shaft_length: v.v[0].hypot(v.v[1]),
            shaft_diameter: 0.1,
            head_length: 0.4,
            head_diameter: 0.3,
            color: Some(color),
        })
}

/// Why the visualization could not start.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct VizError(String);

/// The MCAP file and/or live server a run's boxes go to.
pub struct Viz {
    ctx: Arc<Context>,
    mcap: Mutex<Option<McapWriterHandle<BufWriter<File>>>>,
    server: Mutex<Option<foxglove::WebSocketServerHandle>>,
    scenes: Mutex<HashMap<String, Channel<SceneUpdate>>>,
    stats: Arc<RawChannel>,
}

impl std::fmt::Debug for Viz {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Viz")
    }
}

/// The JSON schema of a `/stats` message.
const STATS_SCHEMA: &str = r#"{"type":"object","properties":{"members":{"type":"array","items":{"type":"string"}},"complete":{"type":"boolean"},"objects":{"type":"integer"},"fusion_ms":{"type":"number"},"e2e_ms":{"type":"number"},"registration":{"type":"object","additionalProperties":{"type":"object","properties":{"pivot":{"type":"array","items":{"type":"number"}},"shift_m":{"type":"array","items":{"type":"number"}},"turn_rad":{"type":"number"},"std":{"type":"array","items":{"type":"number"}},"matches":{"type":"integer"},"chi2":{"type":"number"},"turn_chi2":{"type":"number"},"applied":{"type":"boolean"},"turn_applied":{"type":"boolean"}}}},"learned_std":{"type":"object","additionalProperties":{"type":"object","properties":{"flagged":{"type":"boolean"},"ratio_xy":{"type":["number","null"]},"all":{"type":"object"},"classes":{"type":"object"}}}}}}"#;

impl Viz {
    /// Opens the MCAP file (`mcap`) and/or starts the live server on `live` (host, port); at
    /// least one of them.
    pub async fn open(mcap: Option<&Path>, live: Option<(String, u16)>) -> Result<Viz, VizError> {
        let ctx = Context::new();
        let writer = match mcap {
            Some(p) => Some(
                ctx.mcap_writer()
                    .create(BufWriter::new(File::create(p).map_err(|e| {
                        VizError(format!("cannot create {}: {e}", p.display()))
                    })?))
                    .map_err(|e| VizError(format!("{}: {e}", p.display())))?,
            ),
            None => None,
        };
        let server = match live {
            Some((host, port)) => Some(
                ctx.websocket_server()
                    .name("v2x-fusion")
                    .bind(host.clone(), port)
                    .start()
                    .await
                    .map_err(|e| VizError(format!("Foxglove server on {host}:{port}: {e}")))?,
            ),
            None => None,
        };
        let stats = ctx
            .channel_builder("/stats")
            .message_encoding("json")
            .schema(Schema::new(
                "v2x.WindowStats",
                "jsonschema",
                STATS_SCHEMA.as_bytes(),
            ))
            .build_raw()
            .map_err(|e| VizError(e.to_string()))?;
        Ok(Viz {
            ctx,
            mcap: Mutex::new(writer),
            server: Mutex::new(server),
            scenes: Mutex::new(HashMap::new()),
            stats,
        })
    }

    /// The live server's port, when serving.
    pub fn port(&self) -> Option<u16> {
        self.server.lock().ok()?.as_ref().map(|s| s.port())
    }

    /// Logs boxes from `source` on `topic` at capture time `t_us`.
    pub fn boxes(&self, topic: &str, source: &str, t_us: u64, boxes: &[Detection], rgb: [f64; 3]) {
        self.log_scene(topic, &scene(source, t_us, boxes, rgb), t_us);
    }

    /// Logs a fused frame's boxes on `/fused`, labelled with the agents each came from.
    pub fn fused(&self, t_us: u64, boxes: &[Detection], provenance: &Provenance) {
        let update = scene_with_sources("fused", t_us, boxes, FUSED, Some(provenance));
        self.log_scene("/fused", &update, t_us);
    }

    fn log_scene(&self, topic: &str, update: &SceneUpdate, t_us: u64) {
        let Ok(mut scenes) = self.scenes.lock() else {
            return;
        };
        let channel = scenes
            .entry(topic.to_string())
            .or_insert_with(|| self.ctx.channel_builder(topic).build::<SceneUpdate>());
        channel.log_with_time(update, t_us * 1000);
    }

    /// Logs one fused window's statistics at its reference time, with each registered agent's
    /// estimate when the fuser registers agents.
    #[allow(clippy::too_many_arguments)]
    pub fn window(
        &self,
        t_us: u64,
        members: &[String],
        complete: bool,
        objects: usize,
        fusion_ms: f64,
        e2e_ms: f64,
        registration: &std::collections::BTreeMap<String, crate::time::align::Registration>,
        learned: &std::collections::BTreeMap<String, crate::uncertainty::learn::AgentReport>,
    ) {
        let msg = serde_json::json!({
            "members": members,
            "complete": complete,
            "objects": objects,
            "fusion_ms": fusion_ms,
            "e2e_ms": e2e_ms,
            "registration": registration,
            "learned_std": learned,
        });
        self.stats.log_with_meta(
            msg.to_string().as_bytes(),
            PartialMetadata {
                log_time: Some(t_us * 1000),
            },
        );
    }

    /// Finishes the MCAP file and stops the server.
    pub fn close(&self) -> Result<(), VizError> {
        if let Some(s) = self.server.lock().ok().and_then(|mut s| s.take()) {
            drop(s.stop());
        }
        if let Some(w) = self.mcap.lock().ok().and_then(|mut w| w.take()) {
            w.close()
                .map_err(|e| VizError(format!("closing the MCAP file: {e}")))?;
        }
        Ok(())
    }
}

/// Parses `[ADDR:]PORT` (default address 127.0.0.1).
pub fn parse_listen(s: &str) -> Result<(String, u16), InvalidValue> {
    let (host, port) = match s.rsplit_once(':') {
        Some((h, p)) => (h.to_string(), p),
        None => ("127.0.0.1".to_string(), s),
    };
    let port: u16 = port
        .parse()
        .map_err(|_| InvalidValue::new("listen", "[ADDR:]PORT, e.g. 8765 or 0.0.0.0:8765", s))?;
    Ok((host, port))
}

/// Where to show the boxes, as command-line options: an MCAP file, a live Foxglove server.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct VizArgs {
    /// Record every agent's boxes, the fused boxes (and in simulation the ground truth) and
    /// per-window statistics as Foxglove SceneUpdate messages into this MCAP file.
    #[arg(long)]
    pub mcap: Option<std::path::PathBuf>,
    /// Serve the same live over the Foxglove WebSocket protocol on [ADDR:]PORT (default address
    /// 127.0.0.1); open ws://ADDR:PORT in Foxglove.
    #[arg(long, value_parser = parse_listen)]
    pub foxglove: Option<(String, u16)>,
}

impl VizArgs {
    /// Opens what the options ask for (`None` when neither is given).
    pub async fn open(&self) -> Result<Option<Arc<Viz>>, VizError> {
        if self.mcap.is_none() && self.foxglove.is_none() {
            return Ok(None);
        }
        let v = Viz::open(self.mcap.as_deref(), self.foxglove.clone()).await?;
        if let (Some(port), Some((host, _))) = (v.port(), &self.foxglove) {
            eprintln!("Foxglove: open ws://{host}:{port} in the Foxglove app");
        }
        Ok(Some(Arc::new(v)))
    }
}
