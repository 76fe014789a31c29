//! Opening a Zenoh session: a config file, then CLI flags / environment on top.
//!
//! Every Echo binary shares these flags (like zenoh's own examples):
//! `--zenoh-config`, `--mode`, `--connect`, `--listen`, `--no-multicast-scouting`, `--robot`.

use anyhow::{Context, Result};
use clap::Args;

use crate::RobotId;

/// Network flags shared by every Echo binary.
#[derive(Debug, Clone, Args, Default)]
pub struct BusArgs {
    /// Robot id (namespace of every key).
    #[arg(long, env = "ECHO_ROBOT", default_value = "tiago")]
    pub robot: String,
    /// Zenoh JSON5 config file; the flags below override it.
    #[arg(long = "zenoh-config", env = "ECHO_ZENOH_CONFIG")]
    pub zenoh_config: Option<std::path::PathBuf>,
    /// Session mode: peer, client or router.
    #[arg(long, env = "ECHO_ZENOH_MODE")]
    pub mode: Option<String>,
    /// Endpoint(s) to connect to, e.g. tcp/127.0.0.1:7447 (repeat or comma-separate).
    #[arg(long, env = "ECHO_CONNECT", value_delimiter = ',')]
    pub connect: Vec<String>,
    /// Endpoint(s) to listen on, e.g. tcp/0.0.0.0:7447 (repeat or comma-separate).
    #[arg(long, env = "ECHO_LISTEN", value_delimiter = ',')]
    pub listen: Vec<String>,
    /// Disable multicast scouting (use explicit endpoints; recommended in containers and CI).
    #[arg(long, env = "ECHO_NO_MULTICAST")]
    pub no_multicast_scouting: bool,
    /// Mutual TLS: a directory made by deploy/tls/make-certs (ca.pem, <name>.pem, <name>.key).
    /// Plain TCP is then refused; endpoints are tls/<host>:<port>.
    #[arg(long = "tls-dir", env = "ECHO_TLS_DIR")]
    pub tls_dir: Option<std::path::PathBuf>,
    /// Identity (certificate common name) inside `--tls-dir`; default: the service's name.
    #[arg(long = "tls-name", env = "ECHO_TLS_NAME")]
    pub tls_name: Option<String>,
    /// Messages stamped further ahead of this host's clock than this are refused on receipt
    /// (`from_future`), ms; default 500 (`ingress::DEFAULT_MAX_CLOCK_SKEW_MS`).
    #[arg(long = "max-clock-skew-ms", env = "ECHO_MAX_CLOCK_SKEW_MS")]
    pub max_clock_skew_ms: Option<u64>,
}

impl BusArgs {
    /// Flags for an explicit loopback session: listen on `listen`, connect to `connect`,
    /// multicast scouting off.
    pub fn loopback(robot: &str, listen: &[u16], connect: &[u16]) -> Self {
        BusArgs {
            robot: robot.to_string(),
            zenoh_config: None,
            mode: Some("peer".into()),
            connect: connect
                .iter()
                .map(|p| format!("tcp/127.0.0.1:{p}"))
                .collect(),
            listen: listen
                .iter()
                .map(|p| format!("tcp/127.0.0.1:{p}"))
                .collect(),
            no_multicast_scouting: true,
            tls_dir: None,
            tls_name: None,
            max_clock_skew_ms: None,
        }
    }

    /// These flags as command-line arguments (to start a child process with the same network).
    pub fn to_cli(&self) -> Vec<String> {
        let mut v = vec!["--robot".to_string(), self.robot.clone()];
        if let Some(c) = &self.zenoh_config {
            v.push("--zenoh-config".into());
            v.push(c.display().to_string());
        }
        if let Some(m) = &self.mode {
            v.push("--mode".into());
            v.push(m.clone());
        }
        if !self.connect.is_empty() {
            v.push("--connect".into());
            v.push(self.connect.join(","));
        }
        if !self.listen.is_empty() {
            v.push("--listen".into());
            v.push(self.listen.join(","));
        }
        if self.no_multicast_scouting {
            v.push("--no-multicast-scouting".into());
        }
        if let Some(d) = &self.tls_dir {
            v.push("--tls-dir".into());
            v.push(d.display().to_string());
        }
        if let Some(n) = &self.tls_name {
            v.push("--tls-name".into());
            v.push(n.clone());
        }
        if let Some(ms) = self.max_clock_skew_ms {
            v.push("--max-clock-skew-ms".into());
            v.push(ms.to_string());
        }
        v
    }

    /// Clock skew allowed on receipt, ms ([`crate::ingress::DEFAULT_MAX_CLOCK_SKEW_MS`] unless
    /// `--max-clock-skew-ms` is given).
    pub fn max_clock_skew_ms(&self) -> u64 {
        self.max_clock_skew_ms
            .unwrap_or(crate::ingress::DEFAULT_MAX_CLOCK_SKEW_MS)
    }

    /// These flags with `service`'s TLS identity ([`default_identity`]) unless `--tls-name`
    /// names one.
    pub fn for_service(&self, service: &str) -> BusArgs {
        let mut a = self.clone();
        if a.tls_name.is_none() {
            a.tls_name = Some(default_identity(service).to_string());
        }
        a
    }

    /// The validated robot id.
    pub fn robot_id(&self) -> Result<RobotId> {
        RobotId::new(&self.robot).map_err(|e| anyhow::anyhow!("--robot: {e}"))
    }

    /// Build the Zenoh config.
    pub fn zenoh_config(&self) -> Result<zenoh::Config> {
        let mut cfg = match &self.zenoh_config {
            Some(p) => zenoh::Config::from_file(p)
                .map_err(|e| anyhow::anyhow!("{e}"))
                .with_context(|| format!("reading Zenoh config {}", p.display()))?,
            None => zenoh::Config::default(),
        };
        let set = |cfg: &mut zenoh::Config, key: &str, value: String| -> Result<()> {
            cfg.insert_json5(key, &value)
                .map_err(|e| anyhow::anyhow!("{e}"))
                .with_context(|| format!("setting Zenoh config {key} = {value}"))
        };
        if let Some(m) = &self.mode {
            match m.as_str() {
                "peer" | "client" | "router" => set(&mut cfg, "mode", format!("\"{m}\""))?,
                other => anyhow::bail!("--mode must be peer, client or router, not '{other}'"),
            }
        }
        if !self.connect.is_empty() {
            set(&mut cfg, "connect/endpoints", json_list(&self.connect))?;
        }
        if !self.listen.is_empty() {
            set(&mut cfg, "listen/endpoints", json_list(&self.listen))?;
        }
        if self.no_multicast_scouting {
            set(&mut cfg, "scouting/multicast/enabled", "false".into())?;
        }
        if let Some(dir) = &self.tls_dir {
            let name = self
                .tls_name
                .as_deref()
                .context("--tls-dir needs --tls-name (the certificate's common name)")?;
            let file = |f: String| -> Result<String> {
                let p = dir.join(&f);
                anyhow::ensure!(
                    p.is_file(),
                    "TLS: {} is missing (make it with deploy/tls/make-certs)",
                    p.display()
                );
                Ok(serde_json::to_string(&p.display().to_string())?)
            };
            let (ca, cert, key) = (
                file("ca.pem".into())?,
                file(format!("{name}.pem"))?,
                file(format!("{name}.key"))?,
            );
            let tls = "transport/link/tls";
            set(&mut cfg, &format!("{tls}/root_ca_certificate"), ca)?;
            set(&mut cfg, &format!("{tls}/listen_certificate"), cert.clone())?;
            set(&mut cfg, &format!("{tls}/listen_private_key"), key.clone())?;
            set(&mut cfg, &format!("{tls}/connect_certificate"), cert)?;
            set(&mut cfg, &format!("{tls}/connect_private_key"), key)?;
            set(&mut cfg, &format!("{tls}/enable_mtls"), "true".into())?;
            // Only TLS links: a plain TCP peer cannot join.
            set(&mut cfg, "transport/link/protocols", r#"["tls"]"#.into())?;
        }
        Ok(cfg)
    }
}

/// The certificate identity a service speaks as by default: the stand-ins take the role they
/// play (`mock-robot` → `robot-interface`, `mock-perception` → `perception`), echoctl's tools
/// speak as `operator`, every service as itself.
pub fn default_identity(service: &str) -> &str {
    match service {
        "mock-robot" => "robot-interface",
        "mock-perception" => "perception",
        s if s.starts_with("echoctl") || s == "operator" => "operator",
        s => s,
    }
}

/// A TCP port free on 127.0.0.1 right now.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("binding an ephemeral loopback port")
}

/// `n` free ports, all distinct.
pub fn free_ports(n: usize) -> Vec<u16> {
    let listeners: Vec<_> = (0..n)
        .map(|_| std::net::TcpListener::bind("127.0.0.1:0").expect("binding an ephemeral port"))
        .collect();
    listeners
        .iter()
        .map(|l| l.local_addr().expect("local addr").port())
        .collect()
}

/// Flags for `n` peers on loopback forming a full mesh (each listens on its own port and
/// connects to every other one), multicast scouting off.
pub fn loopback_mesh(robot: &str, n: usize) -> Vec<BusArgs> {
    let ports = free_ports(n);
    (0..n)
        .map(|i| {
            let others: Vec<u16> = ports
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, p)| *p)
                .collect();
            BusArgs::loopback(robot, &[ports[i]], &others)
        })
        .collect()
}

fn json_list(items: &[String]) -> String {
    serde_json::to_string(items).unwrap_or_else(|_| "[]".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_override_and_round_trip() {
        let a = BusArgs::loopback("r1", &[7001], &[7002, 7003]);
        let cfg = a.zenoh_config().unwrap();
        assert!(cfg
            .get_json("connect/endpoints")
            .unwrap()
            .contains("tcp/127.0.0.1:7003"));
        assert_eq!(cfg.get_json("scouting/multicast/enabled").unwrap(), "false");
        let cli = a.to_cli();
        assert!(cli.contains(&"tcp/127.0.0.1:7002,tcp/127.0.0.1:7003".to_string()));
        assert!(!cli.contains(&"--max-clock-skew-ms".to_string()));
        assert_eq!(a.max_clock_skew_ms(), 500);
    }

    #[test]
    fn the_clock_skew_flag_parses_and_passes_on() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            bus: BusArgs,
        }
        use clap::Parser;
        let cli = Cli::try_parse_from(["x", "--max-clock-skew-ms", "1500"]).unwrap();
        assert_eq!(cli.bus.max_clock_skew_ms(), 1500);
        let again =
            Cli::try_parse_from(std::iter::once("x".to_string()).chain(cli.bus.to_cli())).unwrap();
        assert_eq!(again.bus.max_clock_skew_ms, Some(1500));
    }

    #[test]
    fn tls_needs_its_files_and_forbids_plain_tcp() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path().to_path_buf();
        let mut a = BusArgs::loopback("r1", &[], &[]).for_service("safety");
        a.tls_dir = Some(dir.clone());
        let e = a.zenoh_config().unwrap_err().to_string();
        assert!(e.contains("ca.pem") && e.contains("make-certs"), "{e}");
        for f in ["ca.pem", "safety.pem", "safety.key"] {
            std::fs::write(dir.join(f), "x").unwrap();
        }
        let cfg = a.zenoh_config().unwrap();
        assert_eq!(
            cfg.get_json("transport/link/protocols").unwrap(),
            r#"["tls"]"#
        );
        assert!(cfg
            .get_json("transport/link/tls/connect_certificate")
            .unwrap()
            .contains("safety.pem"));
        assert!(a.to_cli().contains(&"--tls-name".to_string()));
        assert_eq!(default_identity("mock-robot"), "robot-interface");
        assert_eq!(default_identity("echoctl-list"), "operator");
    }

    #[test]
    fn bad_mode_and_robot_are_named() {
        let mut a = BusArgs::loopback("r1", &[], &[]);
        a.mode = Some("boss".into());
        assert!(a.zenoh_config().unwrap_err().to_string().contains("boss"));
        a.robot = "a/b".into();
        assert!(a.robot_id().unwrap_err().to_string().contains("--robot"));
    }
}
