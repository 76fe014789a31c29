//! Separate Linux network namespaces joined by veth pairs, for multi-host tests on one machine:
//! `robot` and `edge` each have one link to `router` (addresses only inside the namespaces,
//! 10.99.<n>.0/24). Needs root; [`available`] says why not when it cannot run. Everything is
//! deleted on drop.

use std::process::Command;

use anyhow::{bail, Context, Result};

fn ip(args: &[&str]) -> Result<()> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .context("running ip")?;
    if !out.status.success() {
        bail!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(())
}

/// `Ok` when network namespaces can be made here, else the reason.
pub fn available() -> std::result::Result<(), String> {
    let probe = format!("echo-probe-{}", std::process::id());
    match ip(&["netns", "add", &probe]) {
        Ok(()) => {
            let _ = ip(&["netns", "del", &probe]);
            Ok(())
        }
        Err(e) => Err(format!("network namespaces unavailable (needs root): {e}")),
    }
}

/// Three namespaces: robot —— router —— edge.
pub struct Topology {
    /// Namespace of the robot host.
    pub robot: String,
    /// Namespace of the edge host.
    pub edge: String,
    /// Namespace of the router.
    pub router: String,
    /// The router's address on the robot link.
    pub router_on_robot_link: String,
    /// The router's address on the edge link.
    pub router_on_edge_link: String,
    edge_if: String,
}

impl Topology {
    /// Make the namespaces and links; `net` picks the 10.99.<net>.0/24 and 10.99.<net+1>.0/24
    /// subnets.
    pub fn create(tag: &str, net: u8) -> Result<Topology> {
        let t = Topology {
            robot: format!("{tag}-robot"),
            edge: format!("{tag}-edge"),
            router: format!("{tag}-router"),
            router_on_robot_link: format!("10.99.{net}.2"),
            router_on_edge_link: format!("10.99.{}.2", net + 1),
            edge_if: "ve-edge".into(),
        };
        for ns in [&t.robot, &t.edge, &t.router] {
            let _ = ip(&["netns", "del", ns]);
            ip(&["netns", "add", ns])?;
            ip(&["-n", ns, "link", "set", "lo", "up"])?;
        }
        for (host, ifname, subnet) in [
            (&t.robot, "ve-robot", net),
            (&t.edge, t.edge_if.as_str(), net + 1),
        ] {
            ip(&[
                "-n", host, "link", "add", ifname, "type", "veth", "peer", "name", ifname, "netns",
                &t.router,
            ])?;
            ip(&[
                "-n",
                host,
                "addr",
                "add",
                &format!("10.99.{subnet}.1/24"),
                "dev",
                ifname,
            ])?;
            ip(&[
                "-n",
                &t.router,
                "addr",
                "add",
                &format!("10.99.{subnet}.2/24"),
                "dev",
                ifname,
            ])?;
            ip(&["-n", host, "link", "set", ifname, "up"])?;
            ip(&["-n", &t.router, "link", "set", ifname, "up"])?;
        }
        Ok(t)
    }

    /// Take the edge host's link down (a cable pulled, Wi-Fi gone) or bring it back.
    pub fn set_edge_link(&self, up: bool) -> Result<()> {
        let state = if up { "up" } else { "down" };
        ip(&["-n", &self.edge, "link", "set", &self.edge_if, state])?;
        ip(&["-n", &self.router, "link", "set", &self.edge_if, state])
    }
}

impl Drop for Topology {
    fn drop(&mut self) {
        for ns in [&self.robot, &self.edge, &self.router] {
            let _ = ip(&["netns", "del", ns]);
        }
    }
}
