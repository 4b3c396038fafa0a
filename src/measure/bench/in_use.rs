//! The bench a measurement runs on: the instruments of a bench file, or the built-in mock lab
//! started in-process on 127.0.0.1 (kept alive as long as the [`Bench`]).

use super::bench_file::{BenchCalibration, BenchFile};
use crate::measure::error::MeasureError;
use mock_lab::emulator::lecroy::RemoteInterface;
pub use mock_lab::lab::ScopeModel;
use mock_lab::lab::{Lab, LabOptions};
use mock_lab::scene::Scene;
use mock_lab::server::launch::Transport;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Longest wait for one request on a mock lab's scene control channel.
const CONTROL_TIMEOUT: Duration = Duration::from_secs(5);

/// How to reach the built-in mock lab's AWG (`--awg-transport`, a spec's `awg_transport`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case")]
pub enum AwgLink {
    /// SCPI over a raw TCP socket.
    Raw,
    /// HiSLIP.
    #[default]
    Hislip,
    /// VXI-11 (ONC RPC).
    Vxi11,
}

/// How to reach the built-in mock lab's scope (`--scope-transport`, a spec's `scope_transport`):
/// VICP or VXI-11; a scope served without VICP (the Infiniium) is reached on its default
/// transport (HiSLIP) for `Vicp`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case")]
pub enum ScopeLink {
    /// VICP (a scope without it: its default transport, e.g. HiSLIP).
    #[default]
    Vicp,
    /// VXI-11 (ONC RPC).
    Vxi11,
}

named_enum!(AwgLink, "AWG transport");
named_enum!(ScopeLink, "scope transport");

/// A placeholder resource of the built-in lab's scope `model` for planning (the lab's ports are
/// known only once it runs): one of its default transport.
pub(crate) fn planning_scope_resource(model: ScopeModel) -> &'static str {
    match model.transport(Transport::Vicp) {
        Transport::Vicp => "VICP::127.0.0.1",
        Transport::Vxi11 => "TCPIP::127.0.0.1::inst0::INSTR",
        Transport::Raw => "TCPIP::127.0.0.1::5025::SOCKET",
        Transport::Hislip | Transport::Serial => "TCPIP::127.0.0.1::hislip0::INSTR",
    }
}

/// The built-in mock lab: its scene and the transports to use.
#[derive(Debug, Clone, Default)]
pub struct BuiltIn {
    pub scene: Scene,
    pub awg: AwgLink,
    pub scope: ScopeLink,
    /// Which scope the lab serves (`--scope-model`).
    pub scope_model: ScopeModel,
}

/// Where the bench comes from.
#[derive(Debug, Clone)]
pub enum BenchSource {
    /// A bench file (real instruments, or a `mock-lab serve` started elsewhere).
    File(PathBuf),
    /// The simulated bench, started in-process (boxed: its scene is large).
    BuiltIn(Box<BuiltIn>),
}

/// The bench in use.
pub struct Bench {
    pub file: BenchFile,
    /// The bench file's path (`None` for the built-in lab).
    pub path: Option<PathBuf>,
    /// The built-in lab, when this bench is one.
    pub lab: Option<Lab>,
}

impl Bench {
    /// Opens the bench file, or starts the built-in mock lab (inside the runtime).
    pub async fn open(source: BenchSource) -> Result<Bench, MeasureError> {
        match source {
            BenchSource::File(path) => {
                let file = BenchFile::load(&path)?;
                file.check_models(&file.catalog()?)?;
                Ok(Bench {
                    file,
                    path: Some(path),
                    lab: None,
                })
            }
            BenchSource::BuiltIn(b) => {
                let nominal_delay = b.scene.system_delay_s;
                let jitter = b.scene.trigger_jitter_s;
                let remote = match b.scope {
                    ScopeLink::Vicp => RemoteInterface::Vicp,
                    ScopeLink::Vxi11 => RemoteInterface::Vxi11,
                };
                let lab = mock_lab::lab::start(LabOptions {
                    scene: b.scene,
                    scope_remote: remote,
                    scope_model: b.scope_model,
                    ..LabOptions::default()
                })
                .await?;
                let awg_t = match b.awg {
                    AwgLink::Raw => Transport::Raw,
                    AwgLink::Hislip => Transport::Hislip,
                    AwgLink::Vxi11 => Transport::Vxi11,
                };
                // `vicp` (the default) is the served scope's first transport when it has no VICP.
                let scope_t = b.scope_model.transport(match b.scope {
                    ScopeLink::Vicp => Transport::Vicp,
                    ScopeLink::Vxi11 => Transport::Vxi11,
                });
                let mut file = BenchFile::parse(
                    &lab.bench_toml(awg_t, scope_t),
                    Path::new("<built-in mock lab>"),
                )?;
                // The simulated bench's cables are known exactly: its nominal delay is its
                // calibration.
                // ... and its scope's trigger jitter is its scene's.
                file.scope.trigger_jitter_s = Some(jitter);
                file.calibration = Some(BenchCalibration {
                    system_delay_s: nominal_delay,
                    reference_range_m: None,
                    measured_at: None,
                    response: None,
                });
                Ok(Bench {
                    file,
                    path: None,
                    lab: Some(lab),
                })
            }
        }
    }

    /// Whether the bench is simulated (built in, or a bench file with a `[simulation]` section).
    pub fn is_simulated(&self) -> bool {
        self.lab.is_some() || self.file.simulation.is_some()
    }

    /// One line saying which bench this is, for the user.
    pub fn describe(&self) -> String {
        match (&self.path, &self.lab) {
            (Some(p), _) => format!("bench file {}", p.display()),
            (None, _) => format!(
                "the built-in mock lab (a simulated bench on 127.0.0.1, system delay {:.3} ns)",
                self.file.system_delay_s() * 1e9
            ),
        }
    }

    /// A request on the simulated bench's scene control channel (the in-process lab directly, or
    /// the `[simulation] control` address). `None` on a real bench; an error when the lab
    /// refuses or does not answer.
    pub async fn control(&self, request: &Value) -> Option<Result<Value, String>> {
        if let Some(lab) = &self.lab {
            let reply = lab.bench.scene.apply(&request.to_string());
            return Some(control_reply(reply));
        }
        let address = self.file.simulation.as_ref()?.control.clone();
        Some(
            query_control(&address, &request.to_string())
                .await
                .and_then(control_reply),
        )
    }

    /// The simulated scene of the last capture (ground truth), when the bench is simulated.
    pub(crate) async fn ground_truth(&self) -> Option<Value> {
        if let Some(lab) = &self.lab {
            let (_, scene) = lab.bench.scene.last_capture();
            return scene.and_then(|s| serde_json::to_value(s).ok());
        }
        let reply = self
            .control(&serde_json::json!({"cmd": "last_capture"}))
            .await?;
        reply.ok().and_then(|v| v.get("scene").cloned())
    }
}

fn control_reply(reply: Value) -> Result<Value, String> {
    if reply["ok"] == Value::Bool(true) {
        Ok(reply)
    } else {
        Err(reply["error"]
            .as_str()
            .unwrap_or("the lab refused the request")
            .to_string())
    }
}

/// One request on a mock lab's control channel at `address`, bounded by a timeout.
pub(crate) async fn query_control(address: &str, request: &str) -> Result<Value, String> {
    use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
    let work = async {
        let stream = tokio::net::TcpStream::connect(address)
            .await
            .map_err(|e| format!("cannot connect to the scene control channel {address}: {e}"))?;
        let (rd, mut wr) = stream.into_split();
        wr.write_all(format!("{request}\n").as_bytes())
            .await
            .map_err(|e| format!("scene control channel {address}: {e}"))?;
        let mut line = String::new();
        BufReader::new(rd.take(1 << 20))
            .read_line(&mut line)
            .await
            .map_err(|e| format!("scene control channel {address}: {e}"))?;
        serde_json::from_str::<Value>(&line)
            .map_err(|e| format!("scene control channel {address}: not a JSON reply ({e})"))
    };
    tokio::time::timeout(CONTROL_TIMEOUT, work)
        .await
        .unwrap_or_else(|_| {
            Err(format!(
                "scene control channel {address}: no reply within {} s",
                CONTROL_TIMEOUT.as_secs()
            ))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lab's table of scopes is all radbench needs to serve one: each names a digitizer of the
    /// built-in catalog whose driver family radbench has, by a name that parses back.
    #[test]
    fn every_scope_the_lab_serves_is_a_catalog_digitizer_radbench_opens() {
        let catalog = crate::catalog::Catalog::embedded().unwrap();
        let mut names = std::collections::HashSet::new();
        for m in ScopeModel::ALL {
            assert!(names.insert(m.name()), "{m} twice");
            assert_eq!(m.name().parse::<ScopeModel>().unwrap(), m);
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(serde_json::from_str::<ScopeModel>(&json).unwrap(), m);
            let entry = catalog.get(m.catalog_key()).unwrap();
            assert_eq!(
                entry.instrument.kind,
                crate::catalog::InstrumentKind::Digitizer
            );
            crate::driver::open::check(entry).unwrap_or_else(|e| panic!("{m}: {e}"));
        }
        assert_eq!(ScopeModel::default().name(), "lecroy");
        let uxr: ScopeModel = "keysight-uxr".parse().unwrap();
        assert_eq!(uxr.transport(Transport::Vicp), Transport::Hislip);
        assert_eq!(uxr.transport(Transport::Vxi11), Transport::Vxi11);
        assert_eq!(
            ScopeModel::default().transport(Transport::Vicp),
            Transport::Vicp
        );
        let e = "tek".parse::<ScopeModel>().unwrap_err();
        assert!(e.contains("lecroy, keysight-uxr"), "{e}");
    }
}
