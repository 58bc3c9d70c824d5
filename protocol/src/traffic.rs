//! What a Zenoh session sent and received, from Zenoh's own transport statistics (its `stats`
//! feature): bytes on the wire, transport and network messages, and the payload of puts, in total,
//! per remote session and per key expression of interest. [`stats_pairs`] switches the statistics
//! and the session's admin space on; [`Traffic::parse`] reads the admin space's reply, checked
//! field by field; with the `session` feature, [`traffic`] asks the session for it.
//!
//! Wire bytes are what Zenoh writes to its links: Zenoh framing, declarations, keep-alives and
//! payload, without TCP/IP headers, TLS records or the session's opening handshake.

use serde::Serialize;
use serde_json::Value;
use std::collections::BTreeMap;

/// Counters of one direction (sent or received).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Counters {
    /// Bytes on the wire.
    pub bytes: u64,
    /// Zenoh transport messages (batches).
    pub transport_msgs: u64,
    /// Zenoh network messages (puts, declarations, queries...).
    pub network_msgs: u64,
    /// Puts of user data (the admin space's excluded).
    pub put_msgs: u64,
    /// Payload bytes of those puts.
    pub put_payload_bytes: u64,
}

impl Counters {
    /// `self - earlier`, saturating (counters only grow while a transport lives).
    pub fn since(&self, earlier: &Counters) -> Counters {
        Counters {
            bytes: self.bytes.saturating_sub(earlier.bytes),
            transport_msgs: self.transport_msgs.saturating_sub(earlier.transport_msgs),
            network_msgs: self.network_msgs.saturating_sub(earlier.network_msgs),
            put_msgs: self.put_msgs.saturating_sub(earlier.put_msgs),
            put_payload_bytes: self
                .put_payload_bytes
                .saturating_sub(earlier.put_payload_bytes),
        }
    }

    /// Wire bytes beyond the payload, per put (Zenoh framing and session traffic shared out).
    pub fn overhead_per_put(&self) -> Option<f64> {
        (self.put_msgs > 0).then(|| {
            self.bytes.saturating_sub(self.put_payload_bytes) as f64 / self.put_msgs as f64
        })
    }
}

/// Both directions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Flow {
    /// Sent.
    pub tx: Counters,
    /// Received.
    pub rx: Counters,
}

/// The traffic with one remote session (one transport).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Peer {
    /// The remote session's Zenoh id.
    pub zid: String,
    /// Its mode: `peer`, `client` or `router`.
    pub whatami: String,
    /// Everything exchanged with it.
    pub total: Flow,
    /// Puts per key expression of interest (only put counters are kept per key).
    pub keys: BTreeMap<String, Flow>,
}

/// A session's traffic.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Traffic {
    /// Everything, over every transport the session has had.
    pub total: Flow,
    /// Puts per key expression of interest.
    pub keys: BTreeMap<String, Flow>,
    /// Per remote session still connected.
    pub peers: Vec<Peer>,
}

/// The Zenoh configuration pairs that turn the statistics on, counting puts per key expression in
/// `keys` (the session's admin space is enabled: the statistics are read from it).
pub fn stats_pairs(keys: &[String]) -> Vec<(&'static str, String)> {
    let filters: Vec<Value> = keys
        .iter()
        .map(|k| serde_json::json!({ "key": k }))
        .collect();
    vec![
        ("adminspace/enabled", "true".into()),
        ("adminspace/permissions/read", "true".into()),
        ("stats/filters", Value::Array(filters).to_string()),
    ]
}

/// What is wrong with a field of the statistics.
#[derive(Copy, Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Problem {
    /// It is not there.
    #[error("missing")]
    Missing,
    /// It is not a non-negative integer.
    #[error("not a count")]
    NotCount,
    /// It is not a string.
    #[error("not a string")]
    NotString,
    /// It is not a list.
    #[error("not a list")]
    NotList,
}

/// Why a session's traffic could not be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TrafficError {
    /// The reply is not JSON.
    #[error("not JSON: {0}")]
    NotJson(String),
    /// A field of the reply, by its path (`sessions[1].stats.rx_bytes`).
    #[error("{path}: {problem}")]
    Field {
        /// Where in the reply.
        path: String,
        /// What is wrong there.
        problem: Problem,
    },
    /// The admin space could not be queried.
    #[error("cannot query the admin space: {0}")]
    Query(String),
    /// No statistics came back in time.
    #[error(
        "no statistics from the Zenoh admin space (open the session with traffic::stats_pairs)"
    )]
    NoAnswer,
}

impl TrafficError {
    /// The same error one level further out: `at` goes before its path.
    fn at(self, at: &str) -> TrafficError {
        match self {
            TrafficError::Field { path, problem } => TrafficError::Field {
                path: format!("{at}.{path}"),
                problem,
            },
            e => e,
        }
    }
}

/// A field problem at `path`.
fn bad(path: &str, problem: Problem) -> TrafficError {
    TrafficError::Field {
        path: path.to_string(),
        problem,
    }
}

fn field<'a>(v: &'a Value, name: &str) -> Result<&'a Value, TrafficError> {
    v.get(name).ok_or_else(|| bad(name, Problem::Missing))
}

fn count(v: &Value, name: &str) -> Result<u64, TrafficError> {
    field(v, name)?
        .as_u64()
        .ok_or_else(|| bad(name, Problem::NotCount))
}

/// The user-space part of a `{ "admin": n, "user": n }` counter.
fn user(v: &Value, name: &str) -> Result<u64, TrafficError> {
    count(field(v, name)?, "user").map_err(|e| e.at(name))
}

/// The sum of a `{ "net": n, "shm": n }` counter.
fn medium(v: &Value, name: &str) -> Result<u64, TrafficError> {
    let m = field(v, name)?;
    Ok(count(m, "net").map_err(|e| e.at(name))? + count(m, "shm").map_err(|e| e.at(name))?)
}

fn flow(stats: &Value) -> Result<Flow, TrafficError> {
    let dir = |d: &str| -> Result<Counters, TrafficError> {
        Ok(Counters {
            bytes: count(stats, &format!("{d}_bytes"))?,
            transport_msgs: count(stats, &format!("{d}_t_msgs"))?,
            network_msgs: medium(stats, &format!("{d}_n_msgs"))?,
            put_msgs: user(stats, &format!("{d}_z_put_msgs"))?,
            put_payload_bytes: user(stats, &format!("{d}_z_put_pl_bytes"))?,
        })
    };
    Ok(Flow {
        tx: dir("tx")?,
        rx: dir("rx")?,
    })
}

fn key_flow(stats: &Value) -> Result<Flow, TrafficError> {
    let dir = |d: &str| -> Result<Counters, TrafficError> {
        Ok(Counters {
            put_msgs: user(stats, &format!("{d}_z_put_msgs"))?,
            put_payload_bytes: user(stats, &format!("{d}_z_put_pl_bytes"))?,
            ..Default::default()
        })
    };
    Ok(Flow {
        tx: dir("tx")?,
        rx: dir("rx")?,
    })
}

/// The elements of the list `name` of `v`.
fn list<'a>(v: &'a Value, name: &str) -> Result<&'a Vec<Value>, TrafficError> {
    field(v, name)?
        .as_array()
        .ok_or_else(|| bad(name, Problem::NotList))
}

fn keys_of(v: &Value) -> Result<BTreeMap<String, Flow>, TrafficError> {
    let mut out = BTreeMap::new();
    if v.get("stats_filtered").is_none() {
        return Ok(out);
    }
    for (i, entry) in list(v, "stats_filtered")?.iter().enumerate() {
        let at = format!("stats_filtered[{i}]");
        let key = field(entry, "key")
            .map_err(|e| e.at(&at))?
            .as_str()
            .ok_or_else(|| bad(&format!("{at}.key"), Problem::NotString))?;
        let f = field(entry, "stats")
            .and_then(|s| key_flow(s).map_err(|e| e.at("stats")))
            .map_err(|e| e.at(&at))?;
        out.insert(key.to_string(), f);
    }
    Ok(out)
}

impl Traffic {
    /// Reads the admin space's description of a session queried with `_stats=true`.
    pub fn parse(json: &[u8]) -> Result<Traffic, TrafficError> {
        let v: Value =
            serde_json::from_slice(json).map_err(|e| TrafficError::NotJson(e.to_string()))?;
        let total = flow(field(&v, "stats")?).map_err(|e| e.at("stats"))?;
        let keys = keys_of(&v)?;
        let mut peers = Vec::new();
        for (i, s) in list(&v, "sessions")?.iter().enumerate() {
            let at = format!("sessions[{i}]");
            let text = |name: &str| -> Result<String, TrafficError> {
                Ok(field(s, name)
                    .map_err(|e| e.at(&at))?
                    .as_str()
                    .ok_or_else(|| bad(&format!("{at}.{name}"), Problem::NotString))?
                    .to_string())
            };
            let total = field(s, "stats")
                .and_then(|t| flow(t).map_err(|e| e.at("stats")))
                .map_err(|e| e.at(&at))?;
            peers.push(Peer {
                zid: text("peer")?,
                whatami: text("whatami")?,
                total,
                keys: keys_of(s).map_err(|e| e.at(&at))?,
            });
        }
        Ok(Traffic { total, keys, peers })
    }

    /// The puts counted for `key` (zero if it is not a key of interest).
    pub fn key(&self, key: &str) -> Flow {
        self.keys.get(key).copied().unwrap_or_default()
    }

    /// What was sent over the transports that carried puts on `key` (towards its subscribers):
    /// a publisher's traffic with them, apart from its chatter with other sessions.
    pub fn sent_with(&self, key: &str) -> Counters {
        let mut c = Counters::default();
        for p in &self.peers {
            if p.keys.get(key).is_some_and(|f| f.tx.put_msgs > 0) {
                let t = p.total.tx;
                c.bytes += t.bytes;
                c.transport_msgs += t.transport_msgs;
                c.network_msgs += t.network_msgs;
                c.put_msgs += t.put_msgs;
                c.put_payload_bytes += t.put_payload_bytes;
            }
        }
        c
    }

    /// The one remote session that `key`'s puts came from, when exactly one did and nothing else
    /// of interest came over it: then its received bytes are that sender's alone.
    pub fn sole_sender(&self, key: &str) -> Option<&Peer> {
        let mut from = self
            .peers
            .iter()
            .filter(|p| p.keys.get(key).is_some_and(|f| f.rx.put_msgs > 0));
        let p = from.next()?;
        let alone = p.keys.iter().all(|(k, f)| k == key || f.rx.put_msgs == 0);
        (from.next().is_none() && alone).then_some(p)
    }
}

/// Asks a session for its traffic (its admin space, with `stats_pairs` in its configuration).
#[cfg(feature = "session")]
pub async fn traffic(
    session: &zenoh::Session,
    timeout: std::time::Duration,
) -> Result<Traffic, TrafficError> {
    let zid = session.zid();
    // The session answers for itself at `@/ZID/MODE`; replies from elsewhere are ignored.
    let prefix = format!("@/{zid}/");
    let replies = session
        .get(format!("@/{zid}/*?_stats=true"))
        .timeout(timeout)
        .await
        .map_err(|e| TrafficError::Query(e.to_string()))?;
    let wait = tokio::time::timeout(timeout, async {
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else {
                continue;
            };
            let key = sample.key_expr().as_str();
            if key.starts_with(&prefix) && !key[prefix.len()..].contains('/') {
                return Some(sample.payload().to_bytes().into_owned());
            }
        }
        None
    })
    .await;
    match wait {
        Ok(Some(bytes)) => Traffic::parse(&bytes),
        _ => Err(TrafficError::NoAnswer),
    }
}

#[cfg(test)]
mod tests;
