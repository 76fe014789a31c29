//! `echoctl up --profile <name>`: start what runs on this host (a placement profile from
//! deploy/profiles/) and keep it running — each service a child process, restarted with
//! back-off when it exits, its log lines prefixed with its name on stderr (journald-friendly),
//! all stopped on SIGINT/SIGTERM.
//!
//! Networking: as Zenoh clients of the router given with `--mode client --connect …` (robot +
//! edge and fleet), or, in peer mode, a full mesh on loopback ports (single host).

use anyhow::{anyhow, Result};
use echo_bus::config::free_ports;
use echo_bus::{shutdown, BusArgs};
use echo_launch::profile::{expand, Profile, ServiceSpec, Vars};
use echo_launch::{supervise, Logs, ProcessSpec, RestartPolicy};
use std::path::{Path, PathBuf};

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Profile name (deploy/profiles/<name>.json) or path to a profile file.
    #[arg(long)]
    pub profile: String,
    /// Network and identity, passed on to every service.
    #[command(flatten)]
    pub bus: BusArgs,
    /// The deployment directory (profiles, Zenoh configs).
    #[arg(long, env = "ECHO_DEPLOY_DIR", default_value = "deploy")]
    pub deploy_dir: PathBuf,
    /// Where the model checkpoints are.
    #[arg(long, env = "ECHO_MODELS", default_value = "models")]
    pub models: PathBuf,
    /// Robots the forecaster serves besides --robot (comma-separated).
    #[arg(long, env = "ECHO_SERVE", value_delimiter = ',')]
    pub serve: Vec<String>,
    /// Failover rank of this host's forecaster (0 = primary).
    #[arg(long, env = "ECHO_FORECAST_RANK", default_value_t = 0)]
    pub rank: u32,
    /// Only print what would start.
    #[arg(long)]
    pub dry_run: bool,
}

/// The values `echoctl up` fills into a profile's placeholders: `{models}`, `{deploy}`,
/// `{serve}` (comma-separated), `{rank}`, `{robot}`.
pub fn vars(args: &Args) -> Vars {
    Vars::new()
        .set("models", args.models.display().to_string())
        .set("deploy", args.deploy_dir.display().to_string())
        .set("serve", args.serve.join(","))
        .set("rank", args.rank.to_string())
        .set("robot", args.bus.robot.clone())
}

/// Network flags for each of `n` services.
fn networks(bus: &BusArgs, n: usize) -> Vec<BusArgs> {
    if bus.mode.as_deref() == Some("client") || bus.mode.as_deref() == Some("router") {
        return vec![bus.clone(); n];
    }
    // Peer mode on one host: a full mesh on loopback, plus whatever the host connects to.
    let ports = free_ports(n);
    (0..n)
        .map(|i| {
            let mut a = bus.clone();
            a.mode = Some("peer".into());
            a.no_multicast_scouting = true;
            a.listen.push(format!("tcp/127.0.0.1:{}", ports[i]));
            for (j, p) in ports.iter().enumerate() {
                if j != i {
                    a.connect.push(format!("tcp/127.0.0.1:{p}"));
                }
            }
            a
        })
        .collect()
}

/// The full argument list of service `spec` on network `net`.
pub fn command_line(spec: &ServiceSpec, args: &Args, net: &BusArgs) -> Result<Vec<String>> {
    let mut v = expand(spec, &vars(args))?;
    let mut net = net.clone();
    net.tls_name = Some(spec.identity.clone().unwrap_or_else(|| spec.name.clone()));
    if spec.program == "echoctl" && v.first().is_some_and(|x| x == "router") {
        // The router takes its endpoints from its own config (or the host's own --listen);
        // only identity passes on, never the loopback mesh.
        net = BusArgs {
            robot: net.robot.clone(),
            tls_dir: net.tls_dir.clone(),
            tls_name: net.tls_name.clone(),
            listen: args.bus.listen.clone(),
            ..Default::default()
        };
    }
    if net.tls_dir.is_none() {
        net.tls_name = None;
    }
    v.extend(net.to_cli());
    Ok(v)
}

/// Start the profile and supervise it until SIGINT/SIGTERM.
pub async fn run(args: Args) -> Result<()> {
    let profile = Profile::load(&args.profile, &args.deploy_dir)?;
    let exe_dir = std::env::current_exe()?
        .parent()
        .map(Path::to_path_buf)
        .ok_or_else(|| anyhow!("cannot locate the echoctl binary's directory"))?;
    let nets = networks(&args.bus, profile.services.len());
    let lines: Vec<(ServiceSpec, PathBuf, Vec<String>)> = profile
        .services
        .iter()
        .zip(&nets)
        .map(|(s, n)| {
            Ok((
                s.clone(),
                exe_dir.join(&s.program),
                command_line(s, &args, n)?,
            ))
        })
        .collect::<Result<_>>()?;
    eprintln!("profile {}: {}", args.profile, profile.description);
    for (s, p, a) in &lines {
        eprintln!("  {:<18} {} {}", s.name, p.display(), a.join(" "));
    }
    if args.dry_run {
        return Ok(());
    }
    for (_, p, _) in &lines {
        anyhow::ensure!(
            p.is_file(),
            "{} is missing: build the workspace binaries",
            p.display()
        );
    }
    let stop = shutdown::on_signals();
    let mut tasks = vec![];
    for (spec, program, argv) in lines {
        let mut stop = stop.clone();
        let spec = ProcessSpec::new(&spec.name, program, argv);
        tasks.push(tokio::spawn(async move {
            let label = spec.label.clone();
            let stopped = async move { stop.wait().await };
            if let Err(e) = supervise(spec, Logs::Prefixed, RestartPolicy::default(), stopped).await
            {
                eprintln!("[{label}] {e}");
            }
        }));
    }
    let mut stop = stop;
    stop.wait().await;
    for t in tasks {
        let _ = t.await;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        up: Args,
    }

    fn args(extra: &[&str]) -> Args {
        let mut v = vec!["up", "--profile", "edge", "--deploy-dir", "../../deploy"];
        v.extend(extra);
        Cli::parse_from(v).up
    }

    #[test]
    fn placeholders_fill_and_empty_flags_drop() {
        let prof = Profile::load("edge", Path::new("../../deploy")).unwrap();
        let fc = &prof.services[0];
        let a = args(&["--rank", "1"]);
        let line = expand(fc, &vars(&a)).unwrap();
        assert!(line.contains(&"models/hri".to_string()));
        assert!(!line.contains(&"--robots".to_string()), "{line:?}");
        assert_eq!(line.last().unwrap(), "1");
        let a = args(&["--serve", "r2,r3"]);
        assert!(expand(fc, &vars(&a))
            .unwrap()
            .contains(&"r2,r3".to_string()));
    }

    #[test]
    fn clients_share_the_router_and_peers_mesh_with_identities() {
        let prof = Profile::load("single", Path::new("../../deploy")).unwrap();
        let a = args(&[
            "--mode",
            "client",
            "--connect",
            "tls/10.0.0.1:7447",
            "--tls-dir",
            "/etc/echo/tls",
        ]);
        let nets = networks(&a.bus, prof.services.len());
        let line = command_line(&prof.services[0], &a, &nets[0]).unwrap();
        assert!(line.contains(&"tls/10.0.0.1:7447".to_string()));
        // mock-robot speaks as the robot interface.
        let i = line.iter().position(|x| x == "--tls-name").unwrap();
        assert_eq!(line[i + 1], "robot-interface");
        // The router keeps its own endpoints.
        let router = Profile::load("router-secure", Path::new("../../deploy")).unwrap();
        let a = args(&["--tls-dir", "/etc/echo/tls"]);
        let nets = networks(&a.bus, 1);
        let line = command_line(&router.services[0], &a, &nets[0]).unwrap();
        assert!(!line.iter().any(|x| x.contains("127.0.0.1")), "{line:?}");
        assert!(line.contains(&"router".to_string()));
        let a = args(&[]);
        let nets = networks(&a.bus, 3);
        assert_eq!(nets[0].connect.len(), 2);
        assert_ne!(nets[0].listen, nets[1].listen);
    }
}
