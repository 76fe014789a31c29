//! The shipped Zenoh configurations load, and flags still override them.

use echo_bus::BusArgs;

#[test]
fn shipped_configs_load() {
    for name in ["robot", "edge", "router", "router-secure"] {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../deploy/zenoh/{name}.json5"));
        let args = BusArgs {
            zenoh_config: Some(p.clone()),
            connect: vec!["tcp/10.0.0.2:7447".into()],
            ..Default::default()
        };
        let cfg = args
            .zenoh_config()
            .unwrap_or_else(|e| panic!("{}: {e:#}", p.display()));
        assert_eq!(cfg.get_json("scouting/multicast/enabled").unwrap(), "false");
        assert!(cfg
            .get_json("connect/endpoints")
            .unwrap()
            .contains("10.0.0.2"));
    }
}
