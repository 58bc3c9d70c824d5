//! Zenoh session options as Zenoh users expect them (`--mode`, `-e/--connect`, `-l/--listen`,
//! `--no-multicast-scouting`, `--zenoh-config`), shared by every binary and by scenario files.
//! With the `session` feature, [`open_session`] opens a Zenoh session from them.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Zenoh session options.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct ZenohArgs {
    /// Zenoh mode: peer, client or router (default: the config file's, else peer).
    #[cfg_attr(feature = "cli", arg(long, value_parser = ["peer", "client", "router"]))]
    pub mode: Option<String>,
    /// Endpoints to connect to, e.g. tcp/192.168.1.2:7447 (repeatable).
    #[cfg_attr(feature = "cli", arg(short = 'e', long = "connect"))]
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. tcp/0.0.0.0:7447 (repeatable).
    #[cfg_attr(feature = "cli", arg(short = 'l', long = "listen"))]
    pub listen: Vec<String>,
    /// Disable multicast scouting (discover peers only through --connect).
    #[cfg_attr(feature = "cli", arg(long))]
    pub no_multicast_scouting: bool,
    /// A Zenoh configuration file (JSON5); the options above override it.
    #[cfg_attr(feature = "cli", arg(long))]
    pub zenoh_config: Option<PathBuf>,
}

/// The scenario namespace every key lives under (`v2x/NS/...`), one key chunk.
#[derive(Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct Namespace {
    /// Scenario namespace: every key lives under v2x/NS/ (letters, digits, '-', '_' or '.').
    #[cfg_attr(feature = "cli", arg(long = "ns", value_name = "NS", default_value = "default", value_parser = parse_namespace))]
    pub ns: String,
}

/// A namespace, checked to be one key chunk without wildcards.
pub fn parse_namespace(s: &str) -> Result<String, crate::keys::NameError> {
    crate::keys::validate_chunk("namespace", s)?;
    Ok(s.to_string())
}

impl ZenohArgs {
    /// The (key, JSON5 value) pairs to insert into a Zenoh config.
    pub fn json5_pairs(&self) -> Vec<(&'static str, String)> {
        let list = |v: &[String]| serde_json::to_string(v).expect("strings serialize");
        let mut out = Vec::new();
        if let Some(m) = &self.mode {
            out.push(("mode", format!("\"{m}\"")));
        }
        if !self.connect.is_empty() {
            out.push(("connect/endpoints", list(&self.connect)));
        }
        if !self.listen.is_empty() {
            out.push(("listen/endpoints", list(&self.listen)));
        }
        if self.no_multicast_scouting {
            out.push(("scouting/multicast/enabled", "false".into()));
        }
        out
    }

    /// Options for a loopback-only session: no multicast, listening and connecting as given.
    pub fn loopback(listen: &[String], connect: &[String]) -> Self {
        ZenohArgs {
            mode: Some("peer".into()),
            connect: connect.to_vec(),
            listen: listen.to_vec(),
            no_multicast_scouting: true,
            zenoh_config: None,
        }
    }
}

/// Why a Zenoh session could not be opened; the message names the file or option at fault.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SessionError(pub String);

impl std::fmt::Display for SessionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for SessionError {}

/// The Zenoh encoding of a frame payload: bytes, schema `v2x-frame/VERSION`.
#[cfg(feature = "session")]
pub fn frame_encoding() -> zenoh::bytes::Encoding {
    zenoh::bytes::Encoding::APPLICATION_OCTET_STREAM
        .with_schema(format!("v2x-frame/{}", crate::wire::VERSION))
}

/// The Zenoh encoding of an ETSI CPM payload (UPER), which agents may send on their
/// detections key instead of a frame: bytes, schema `etsi-cpm-uper/2`.
#[cfg(feature = "session")]
pub fn cpm_encoding() -> zenoh::bytes::Encoding {
    zenoh::bytes::Encoding::APPLICATION_OCTET_STREAM.with_schema(CPM_SCHEMA)
}

/// The schema of [`cpm_encoding`].
pub const CPM_SCHEMA: &str = "etsi-cpm-uper/2";

/// Whether a sample's encoding says it carries a CPM (else it is a frame).
#[cfg(feature = "session")]
pub fn is_cpm(encoding: &zenoh::bytes::Encoding) -> bool {
    *encoding == cpm_encoding()
}

/// The Zenoh configuration these options describe (the config file first, then the flags).
#[cfg(feature = "session")]
pub fn config(args: &ZenohArgs) -> Result<zenoh::Config, SessionError> {
    let mut config = match &args.zenoh_config {
        Some(p) => zenoh::Config::from_file(p).map_err(|e| {
            SessionError(format!("{}: invalid Zenoh configuration: {e}", p.display()))
        })?,
        None => zenoh::Config::default(),
    };
    for (key, value) in args.json5_pairs() {
        config
            .insert_json5(key, &value)
            .map_err(|e| SessionError(format!("Zenoh option {key} = {value}: {e}")))?;
    }
    // Zenoh reassembles messages up to 1 GiB by default: bound it by the format's own limit,
    // unless the configuration file chose a value.
    let default = zenoh::Config::default()
        .get_json(MAX_MESSAGE_KEY)
        .unwrap_or_default();
    if config.get_json(MAX_MESSAGE_KEY).unwrap_or_default() == default {
        let value = crate::limits::MAX_MESSAGE.to_string();
        config
            .insert_json5(MAX_MESSAGE_KEY, &value)
            .map_err(|e| SessionError(format!("Zenoh option {MAX_MESSAGE_KEY} = {value}: {e}")))?;
    }
    Ok(config)
}

/// The Zenoh option that bounds the size of a reassembled message.
pub const MAX_MESSAGE_KEY: &str = "transport/link/rx/max_message_size";

/// Opens a Zenoh session with the given options (the config file first, then the flags).
#[cfg(feature = "session")]
pub async fn open_session(args: &ZenohArgs) -> Result<zenoh::Session, SessionError> {
    zenoh::open(config(args)?)
        .await
        .map_err(|e| SessionError(format!("cannot open a Zenoh session: {e}")))
}

/// Opens a Zenoh session whose transport statistics count puts per key expression in `keys`
/// (read them with [`crate::traffic::traffic`]).
#[cfg(feature = "session")]
pub async fn open_counted_session(
    args: &ZenohArgs,
    keys: &[String],
) -> Result<zenoh::Session, SessionError> {
    let mut config = config(args)?;
    for (key, value) in crate::traffic::stats_pairs(keys) {
        config
            .insert_json5(key, &value)
            .map_err(|e| SessionError(format!("Zenoh option {key} = {value}: {e}")))?;
    }
    zenoh::open(config)
        .await
        .map_err(|e| SessionError(format!("cannot open a Zenoh session: {e}")))
}

/// Logs to stderr at the levels `RUST_LOG` names, else at `default` (e.g. `info,zenoh=warn`).
#[cfg(feature = "cli")]
pub fn init_logging(default: &str) {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| default.into()),
        )
        .with_writer(std::io::stderr)
        .init();
}

/// A binary's exit: success, or its error on one line with its causes (for people: no
/// backtrace).
pub fn exit_code<E: std::fmt::Display>(result: Result<(), E>) -> std::process::ExitCode {
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// The multi-threaded async runtime every binary runs its network work on.
#[cfg(feature = "session")]
pub fn runtime() -> Result<tokio::runtime::Runtime, SessionError> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| SessionError(format!("cannot start the async runtime: {e}")))
}

/// Resolves on SIGINT (Ctrl-C) or SIGTERM (systemd, `docker stop`, `timeout`).
#[cfg(feature = "session")]
pub async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs() {
        let a = ZenohArgs::loopback(&["tcp/127.0.0.1:7001".into()], &[]);
        let p = a.json5_pairs();
        assert!(p.contains(&("mode", "\"peer\"".into())));
        assert!(p.contains(&("listen/endpoints", "[\"tcp/127.0.0.1:7001\"]".into())));
        assert!(p.contains(&("scouting/multicast/enabled", "false".into())));
        assert!(ZenohArgs::default().json5_pairs().is_empty());
    }

    #[cfg(feature = "session")]
    #[test]
    fn a_cpm_is_told_from_a_frame_by_its_encoding_as_documented() {
        assert!(is_cpm(&cpm_encoding()));
        assert!(!is_cpm(&frame_encoding()));
        assert!(!is_cpm(&zenoh::bytes::Encoding::APPLICATION_OCTET_STREAM));
        assert_eq!(
            cpm_encoding().to_string(),
            "application/octet-stream;etsi-cpm-uper/2"
        );
        assert_eq!(
            frame_encoding().to_string(),
            format!(
                "application/octet-stream;v2x-frame/{}",
                crate::wire::VERSION
            )
        );
    }

    #[cfg(feature = "session")]
    #[test]
    fn messages_are_bounded_by_the_format_unless_a_file_says_otherwise() {
        let c = config(&ZenohArgs::default()).unwrap();
        let want = crate::limits::MAX_MESSAGE.to_string();
        assert_eq!(c.get_json(MAX_MESSAGE_KEY).unwrap(), want);
        let dir = std::env::temp_dir().join(format!("v2x-net-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("z.json5");
        std::fs::write(&file, "{transport: {link: {rx: {max_message_size: 4096}}}}").unwrap();
        let args = ZenohArgs {
            zenoh_config: Some(file),
            ..Default::default()
        };
        assert_eq!(
            config(&args).unwrap().get_json(MAX_MESSAGE_KEY).unwrap(),
            "4096"
        );
        let _ = std::fs::remove_dir_all(dir);
    }
}
