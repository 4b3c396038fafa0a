//! The scope: reachable, identified, and answering on the remote interface the bench file
//! names. A scope that does not answer there is asked on its other interface at the same host
//! when its family serves one interface at a time (LeCroy: VICP or VXI-11), since it looks dead
//! when set to the other (the remote-interface trap); a family serving its interfaces side by
//! side is not asked elsewhere. The fix names where the scope's family sets it
//! ([`open::scope_remote_setting`]).

use super::bounds::{bounded, Deadline, OPEN_TIMEOUT};
use super::checklist::List;
use super::connect::Probe;
use super::entries::Entry;
use super::identity::reach_and_identity;
use crate::address::Resource;
use crate::driver::open::{self, RemoteSetting};
use crate::measure::bench::in_use::Bench;

/// `scope.reachable`, `scope.identity` and `scope.remote_interface`, from the probe and `idn`,
/// the scope's identity on the bench file's resource (or why it has none).
pub(super) async fn check_scope(
    list: &mut List,
    bench: &Bench,
    scope: &Entry,
    probe: &Probe,
    idn: &Result<String, String>,
    deadline: Deadline,
) {
    let unanswered =
        matches!(probe, Some(Err(_))) || matches!(idn, Err(e) if e.contains("remote interface"));
    if unanswered {
        unanswered_scope(list, bench, scope, probe, idn, deadline).await;
    } else {
        reach_and_identity(list, scope, probe, idn);
        if idn.is_ok() {
            list.pass(
                "scope.remote_interface",
                format!(
                    "the scope answers over {}, as the bench file says",
                    interface_name(scope.resource.protocol())
                ),
            );
        } else {
            list.skip("scope.remote_interface", "the scope was not identified");
        }
    }
}

/// A scope silent on the bench file's interface, asked on the other one: answering there, it is
/// set to that interface; answering on neither, it is off, elsewhere, or set to something else.
async fn unanswered_scope(
    list: &mut List,
    bench: &Bench,
    scope: &Entry,
    probe: &Probe,
    idn: &Result<String, String>,
    deadline: Deadline,
) {
    let setting = open::scope_remote_setting(&scope.model);
    // Only a family that serves one interface at a time is asked on the other: one that serves
    // them side by side (HiSLIP, VXI-11 and a socket together) has no other to be set to.
    let other = match setting {
        RemoteSetting::OneAtATime { .. } => {
            other_scope_resource(bench, &scope.resource, deadline).await
        }
        RemoteSetting::SideBySide { .. } => None,
    };
    let other_answer = match &other {
        Some(r) => bounded(
            deadline,
            open::open_digitizer(r.clone(), &scope.model, None, "scope"),
        )
        .await
        .map(|s| s.identity().to_string()),
        None => Err("no other interface to try".into()),
    };
    let this = interface_name(scope.resource.protocol());
    match (other, other_answer) {
        (Some(r), Ok(idn)) => {
            let that = interface_name(r.protocol());
            list.pass(
                "scope.reachable",
                format!("the scope answers at {r} ({idn}), not at {}", scope.written),
            );
            list.skip("scope.identity", "checked on the other interface only");
            let rewrite = format!("write resource = \"{r}\" in the bench file's [scope]");
            list.fail(
                "scope.remote_interface",
                format!(
                    "the scope does not answer over {this} as the bench file says, but does \
                     over {that}: its remote interface is set to {that}"
                ),
                match setting {
                    RemoteSetting::OneAtATime { menu } => {
                        format!("on the scope set {menu} to {this}, or {rewrite}")
                    }
                    RemoteSetting::SideBySide { .. } => rewrite,
                },
            );
        }
        (tried, _) => {
            reach_and_identity(list, scope, probe, idn);
            let look_at = match setting {
                RemoteSetting::OneAtATime { menu } => menu,
                RemoteSetting::SideBySide { look_at } => look_at,
            };
            list.fail(
                "scope.remote_interface",
                match tried {
                    Some(r) => format!(
                        "the scope answers neither over {this} nor over {} ({r})",
                        interface_name(r.protocol())
                    ),
                    None => format!("the scope does not answer over {this}"),
                },
                format!("check that the scope is on, its host, and {look_at}"),
            );
        }
    }
}

/// The scope's other remote interface at the same host: the resource to try, from the lab's
/// endpoint list on a simulated bench, else the protocol's standard port.
async fn other_scope_resource(
    bench: &Bench,
    resource: &Resource,
    deadline: Deadline,
) -> Option<Resource> {
    let want = match resource {
        Resource::Vicp { .. } => "vxi11",
        Resource::Vxi11 { .. } => "vicp",
        _ => return None,
    };
    let request = serde_json::json!({"cmd": "endpoints"});
    let asked = bench.control(&request);
    if let Ok(Some(Ok(reply))) = tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), asked).await {
        let found = reply["endpoints"].as_array().and_then(|list| {
            list.iter()
                .find(|e| e["instrument"] == "scope" && e["transport"] == want)
                .and_then(|e| e["resource"].as_str())
                .and_then(|r| r.parse().ok())
        });
        if found.is_some() {
            return found;
        }
    }
    let host = resource.host()?;
    let text = if want == "vicp" {
        format!("VICP::{host}::INSTR")
    } else {
        format!("TCPIP0::{host}::inst0::INSTR")
    };
    text.parse().ok()
}

fn interface_name(protocol: &str) -> &'static str {
    match protocol {
        "vicp" => "TCPIP (VICP)",
        "hislip" => "HiSLIP",
        "socket" => "a raw socket",
        _ => "LXI (VXI-11)",
    }
}
