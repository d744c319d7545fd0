//! The bridge's Zenoh session: peer mode, TCP only, connect retried forever.

use std::str::FromStr;

use anyhow::{anyhow, bail, Context, Result};
use zenoh::config::EndPoint;
use zenoh::{Config, Session, Wait};

/// Where the session finds its peers.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Network {
    /// Endpoints to connect to (a router or peer), e.g. `tcp/192.168.1.10:7447`.
    pub connect: Vec<String>,
    /// Endpoints to listen on; Zenoh's default (`tcp/[::]:0`) when empty.
    pub listen: Vec<String>,
    /// Find peers on the LAN by UDP multicast scouting (off in rmw_zenoh's defaults).
    pub multicast: bool,
}

/// Checks one endpoint: Zenoh's syntax, the `tcp` protocol (the only transport built
/// in) and an address ending in a port.
pub fn check_endpoint(text: &str) -> Result<EndPoint> {
    let endpoint = EndPoint::from_str(text).map_err(|e| anyhow!("bad endpoint {text:?}: {e}"))?;
    let protocol = endpoint.protocol();
    if protocol.as_str() != "tcp" {
        bail!("bad endpoint {text:?}: protocol {protocol:?}, but only tcp is built in (e.g. tcp/192.168.1.10:7447)");
    }
    let address = endpoint.address();
    let port = address.as_str().rsplit_once(':').map(|(_, p)| p);
    if port.is_none_or(|p| p.parse::<u16>().is_err()) {
        bail!("bad endpoint {text:?}: the address {address} has no port (e.g. tcp/192.168.1.10:7447)");
    }
    Ok(endpoint)
}

impl Network {
    /// Checks every endpoint (see [`check_endpoint`]).
    pub fn check(&self) -> Result<()> {
        for e in self.connect.iter().chain(&self.listen) {
            check_endpoint(e)?;
        }
        Ok(())
    }

    /// The Zenoh configuration: peer mode; connections retried in the background, forever
    /// and also after a peer was lost, so the bridge reconnects by itself.
    pub fn config(&self) -> Result<Config> {
        let mut config = Config::default();
        let json = |v: &[String]| serde_json::to_string(v).unwrap_or_else(|_| "[]".into());
        let mut set = |key: &str, value: &str| {
            config
                .insert_json5(key, value)
                .map_err(|e| anyhow!("zenoh configuration {key} = {value}: {e}"))
        };
        set("mode", "\"peer\"")?;
        set("connect/endpoints", &json(&self.connect))?;
        set("connect/timeout_ms", "-1")?;
        set("connect/exit_on_failure", "false")?;
        // A lost peer is tried again after 0.5 s, then at most every 2 s (Zenoh: 1 s, 4 s).
        set(
            "connect/retry",
            "{ period_init_ms: 500, period_max_ms: 2000, period_increase_factor: 2 }",
        )?;
        if !self.listen.is_empty() {
            set("listen/endpoints", &json(&self.listen))?;
        }
        set(
            "scouting/multicast/enabled",
            if self.multicast { "true" } else { "false" },
        )?;
        Ok(config)
    }

    /// Opens the session (returns at once even when no peer is reachable yet).
    pub fn open(&self) -> Result<Session> {
        self.check()?;
        zenoh::open(self.config()?)
            .wait()
            .map_err(|e| anyhow!("{e}"))
            .context("cannot open the Zenoh session")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_are_checked() {
        assert!(check_endpoint("tcp/192.168.1.10:7447").is_ok());
        assert!(check_endpoint("tcp/[::1]:7447").is_ok());
        assert!(check_endpoint("tcp/router.local:7447").is_ok());
        for bad in [
            "192.168.1.10:7447",
            "udp/10.0.0.1:7447",
            "tcp/10.0.0.1",
            "tcp/h:99999",
            "",
        ] {
            let e = check_endpoint(bad).expect_err(bad).to_string();
            assert!(e.starts_with("bad endpoint"), "{bad}: {e}");
        }
    }

    #[test]
    fn the_config_takes_every_setting() {
        let net = Network {
            connect: vec!["tcp/127.0.0.1:7447".into()],
            listen: vec!["tcp/127.0.0.1:0".into()],
            multicast: false,
        };
        net.config().expect("config");
    }
}
