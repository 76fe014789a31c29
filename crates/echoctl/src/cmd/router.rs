//! `echoctl router`: a Zenoh router from the same library the services use (the upstream
//! `zenohd` reads the same configuration file, deploy/zenoh/router.json5).

use anyhow::{anyhow, Result};
use echo_bus::BusArgs;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network (the mode is forced to router; default listen tcp/0.0.0.0:7447).
    #[command(flatten)]
    pub bus: BusArgs,
}

/// Run a router until SIGINT/SIGTERM.
pub async fn run(mut args: Args) -> Result<()> {
    args.bus.mode = Some("router".into());
    if args.bus.listen.is_empty() && args.bus.zenoh_config.is_none() {
        args.bus.listen = vec!["tcp/0.0.0.0:7447".into()];
    }
    let cfg = args.bus.for_service("router").zenoh_config()?;
    let acl = cfg
        .get_json("access_control/enabled")
        .is_ok_and(|v| v == "true");
    let session = zenoh::open(cfg)
        .await
        .map_err(|e| anyhow!("starting the router: {e}"))?;
    tracing::info!(zid = %session.zid(), listen = ?args.bus.listen, access_control = acl, "router running");
    echo_bus::shutdown::signal().await;
    session
        .close()
        .await
        .map_err(|e| anyhow!("closing the router: {e}"))
}
