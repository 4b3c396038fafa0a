//! The catalog limits `doctor --verify-catalog` reads from an instrument, per driver family, in
//! the family's own commands. Nothing radiates; what a check changes (a LeCroy setting pushed out
//! of range to read its limit, the M8195A's memory mode of an empty channel 1) is put back.
//!
//! | family | field | how |
//! |---|---|---|
//! | `keysight-m8195a` | `awg.dac_rate_min` / `max` / `default` | `:FREQ:RAST? MIN` / `MAX` / `DEF` |
//! | `keysight-m8195a` | `awg.internal_memory_samples`, `awg.extended_memory_samples` | `:TRAC1:FREE?` plus the lengths in `:TRAC1:CAT?`, in each `:TRAC1:MMOD`; the other mode only when channel 1 holds no segment |
//! | `lecroy-maui` | `digitizer.volts_per_div_min` / `max` | `C1:VDIV` set beyond the range, read back (the scope adapts it), restored |
//! | `lecroy-maui` | `digitizer.max_points_per_channel` | `MSIZ` likewise |
//! | `lecroy-maui` | `digitizer.sample_rates` (highest) | `app.Acquisition.Horizontal.SampleRate` likewise (VBS) |
//! | `lecroy-maui` | `digitizer.max_sequence_segments` | `app.Acquisition.Horizontal.NumSegments` likewise (VBS) |

use super::ask::{ask_once, probe_limit, reply_number, Probe};
use super::error::{session, DriverError};
use super::family::DriverFamily;
use super::io::open_session;
use crate::address::Resource;
use crate::catalog::InstrumentModel;
use crate::session::Session;
use crate::transport::Journal;
use std::time::Duration;

/// One limit as read: the field (as in the instrument file) and the number, or why there is none.
pub(crate) type ReadLimit = (&'static str, Result<f64, String>);

/// Where the instrument is and how long each exchange may take.
pub(crate) struct Reach<'a> {
    pub resource: Resource,
    pub model: &'a InstrumentModel,
    pub limit: Duration,
    pub journal: Option<Journal>,
    pub name: &'a str,
}

/// The limits `family` has queries for, read from the instrument (empty: none known).
pub(crate) async fn read_limits(family: DriverFamily, reach: &Reach<'_>) -> Vec<ReadLimit> {
    match family {
        DriverFamily::KeysightM8195a => m8195a(reach).await,
        DriverFamily::LecroyMaui => lecroy(reach).await,
        DriverFamily::KeysightInfiniium | DriverFamily::GotmicLine => Vec::new(),
    }
}

async fn ask_number(reach: &Reach<'_>, query: &str) -> Result<f64, String> {
    let reply = ask_once(
        reach.resource.clone(),
        reach.model,
        query,
        reach.limit,
        reach.journal.clone(),
        reach.name,
    )
    .await?;
    reply_number(&reply).ok_or_else(|| format!("{query} answered {reply:?}, not a number"))
}

async fn m8195a(reach: &Reach<'_>) -> Vec<ReadLimit> {
    let mut out = vec![
        (
            "awg.dac_rate_min",
            ask_number(reach, ":FREQ:RAST? MIN").await,
        ),
        (
            "awg.dac_rate_max",
            ask_number(reach, ":FREQ:RAST? MAX").await,
        ),
        (
            "awg.dac_rate_default",
            ask_number(reach, ":FREQ:RAST? DEF").await,
        ),
    ];
    let (internal, extended) = match tokio::time::timeout(reach.limit * 2, memories(reach)).await {
        Ok(Ok(both)) => both,
        Ok(Err(why)) => (Err(why.clone()), Err(why)),
        Err(_) => {
            let why = "no answer about channel 1's memory in time".to_string();
            (Err(why.clone()), Err(why))
        }
    };
    out.push(("awg.internal_memory_samples", internal));
    out.push(("awg.extended_memory_samples", extended));
    out
}

type Memories = (Result<f64, String>, Result<f64, String>);

/// Channel 1's capacity in its current memory mode (free + the lengths of its segments); in the
/// other mode too when channel 1 holds no segment (switching deletes them), switching back after.
async fn memories(reach: &Reach<'_>) -> Result<Memories, String> {
    let as_text = |e| DriverError::to_string(&session(reach.name)(e));
    let mut s = open_session(
        reach.resource.clone(),
        reach.model,
        "",
        reach.journal.clone(),
        reach.name,
    )
    .await
    .map_err(as_text)?;
    let mode = s.query(":TRAC1:MMOD?").await.map_err(as_text)?;
    let mode = mode.trim().to_ascii_uppercase();
    let extended_now = mode.starts_with("EXT");
    let (here, empty) = capacity(&mut s, reach.name).await?;
    let (there_kw, back_kw) = if extended_now {
        ("INT", "EXT")
    } else {
        ("EXT", "INT")
    };
    let there = if !empty {
        Err(format!(
            "not read: channel 1 holds a waveform in {mode} memory, and switching its memory mode \
             (:TRAC1:MMOD {there_kw}) would delete it; run the check again on a freshly started AWG"
        ))
    } else {
        s.write(&format!(":TRAC1:MMOD {there_kw}"))
            .await
            .map_err(as_text)?;
        let switched = s.query(":TRAC1:MMOD?").await.map_err(as_text)?;
        let read = if switched.trim().to_ascii_uppercase().starts_with(there_kw) {
            capacity(&mut s, reach.name).await.map(|(c, _)| c)
        } else {
            Err(format!(
                "not read: the AWG kept channel 1 in {mode} memory when asked for {there_kw} \
                 (running, or its DAC mode plays channel 1 from one memory only)"
            ))
        };
        s.write(&format!(":TRAC1:MMOD {back_kw}"))
            .await
            .map_err(as_text)?;
        // Read the mode back before the session closes: a write left in flight could otherwise
        // be carried out after whatever the next session asks.
        let back = s.query(":TRAC1:MMOD?").await.map_err(as_text)?;
        if !back.trim().to_ascii_uppercase().starts_with(back_kw) {
            return Err(format!(
                "channel 1 stayed in {back} memory when set back to {back_kw}: set \
                 :TRAC1:MMOD {back_kw} by hand"
            ));
        }
        read
    };
    Ok(if extended_now {
        (there, Ok(here))
    } else {
        (Ok(here), there)
    })
}

/// Channel 1's capacity in its current memory mode, and whether it holds no segment.
async fn capacity(s: &mut Session, name: &str) -> Result<(f64, bool), String> {
    let as_text = |e| DriverError::to_string(&session(name)(e));
    let catalog = s.query(":TRAC1:CAT?").await.map_err(as_text)?;
    // `id,length[,id,length...]`, `0,0` when empty.
    let numbers: Vec<f64> = catalog
        .trim()
        .split(',')
        .filter_map(|t| t.trim().parse::<f64>().ok())
        .collect();
    let used: f64 = numbers.iter().skip(1).step_by(2).sum();
    let free = s.query(":TRAC1:FREE?").await.map_err(as_text)?;
    let free = reply_number(&free)
        .ok_or_else(|| format!(":TRAC1:FREE? answered {free:?}, not a number"))?;
    Ok((free + used, used == 0.0))
}

async fn lecroy(reach: &Reach<'_>) -> Vec<ReadLimit> {
    let probes: [(&'static str, Probe<'_>); 5] = [
        (
            "digitizer.volts_per_div_min",
            Probe {
                query: "C1:VDIV?",
                set: "C1:VDIV {}",
                beyond: 1e-9,
            },
        ),
        (
            "digitizer.volts_per_div_max",
            Probe {
                query: "C1:VDIV?",
                set: "C1:VDIV {}",
                beyond: 1e6,
            },
        ),
        (
            "digitizer.max_points_per_channel",
            Probe {
                query: "MSIZ?",
                set: "MSIZ {}",
                beyond: 1e15,
            },
        ),
        (
            "digitizer.sample_rates",
            Probe {
                query: "VBS? 'return=app.Acquisition.Horizontal.SampleRate'",
                set: "VBS 'app.Acquisition.Horizontal.SampleRate={}'",
                beyond: 1e15,
            },
        ),
        (
            "digitizer.max_sequence_segments",
            Probe {
                query: "VBS? 'return=app.Acquisition.Horizontal.NumSegments'",
                set: "VBS 'app.Acquisition.Horizontal.NumSegments={}'",
                beyond: 1e9,
            },
        ),
    ];
    let mut out = Vec::new();
    for (field, probe) in &probes {
        let read = probe_limit(
            reach.resource.clone(),
            reach.model,
            probe,
            reach.limit,
            reach.journal.clone(),
            reach.name,
        )
        .await;
        out.push((*field, read));
    }
    out
}
