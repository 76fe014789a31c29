//! Messages on the edge every service → operators.

use super::*;

/// Latency summary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LatencySummary {
    /// Median, ms.
    pub median_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// Samples in the window.
    pub samples: u64,
}

/// A service's health and counters, published once per second and on shutdown.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ServiceStatus {
    /// Header.
    pub header: Header,
    /// Service name.
    pub service: String,
    /// Seconds since start.
    pub uptime_s: f64,
    /// Messages received per input.
    pub received: BTreeMap<String, u64>,
    /// Messages published per output.
    pub published: BTreeMap<String, u64>,
    /// Rejected inputs by reason ("<input>/<reason>").
    pub rejected: BTreeMap<String, u64>,
    /// Messages dropped by queue policy per input.
    pub dropped: BTreeMap<String, u64>,
    /// Most recent rejection, with its full reason.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_error: Option<String>,
    /// Processing latency per message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency: Option<LatencySummary>,
    /// Free-form state notes (e.g. "forecasting human only").
    #[serde(default)]
    pub notes: Vec<String>,
}
message!(ServiceStatus, "service_status");

impl Validate for ServiceStatus {
    fn validate(&self) -> Result<(), ValidationError> {
        check_identifier("service", &self.service)?;
        check_finite("uptime_s", &[self.uptime_s])
    }
}
