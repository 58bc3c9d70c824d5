//! `v2x-sim certs`.

/// The options of `v2x-sim certs`.
#[derive(clap::Args)]
pub struct CertsArgs {
    #[command(flatten)]
    pub out: v2x_protocol::cli::Output,
    #[command(flatten)]
    pub ns: v2x_protocol::net::Namespace,
    /// Endpoints the router listens on.
    #[arg(long, default_value = "tls/0.0.0.0:7447")]
    pub listen: Vec<String>,
    /// Endpoints the clients connect to; their hosts are written into the router's
    /// certificate (with localhost and 127.0.0.1).
    #[arg(long, default_value = "tls/localhost:7447")]
    pub router: Vec<String>,
    /// Days the certificates are valid.
    #[arg(long, default_value_t = 365)]
    pub days: u32,
    /// The agents' names, one certificate each.
    #[arg(required = true)]
    pub agents: Vec<String>,
}

/// Runs `v2x-sim certs`.
pub fn run(args: CertsArgs) -> anyhow::Result<()> {
    let CertsArgs {
        out: v2x_protocol::cli::Output { path: out },
        ns,
        listen,
        router,
        days,
        agents,
    } = args;
    let issued = v2x_sim::certs::issue(&v2x_sim::certs::CertsConfig {
        out,
        ns: ns.ns,
        agents,
        listen,
        connect: router,
        days,
    })?;
    println!(
        "wrote certificates and Zenoh configurations to {}:",
        issued.dir.display()
    );
    println!(
        "  router:   v2x-fuser router --zenoh-config {}",
        issued.router.display()
    );
    println!(
        "  fuser:    v2x-fuser node --zenoh-config {} ...",
        issued.fuser.display()
    );
    for (a, p) in &issued.agents {
        println!(
            "  agent {a}: v2x-agent FILE --name {a} --zenoh-config {} ...",
            p.display()
        );
    }
    println!(
        "  observer: v2x-fuser stats --zenoh-config {}",
        issued.observer.display()
    );
    println!("keep ca-key.pem and the *-key.pem files private");
    Ok(())
}
