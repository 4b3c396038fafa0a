//! The answer a report leads with: pass or fail against the bound, the worst error, the false
//! targets and chain echoes, then who ran what when (date, duration, operator), on which
//! instruments (`*IDN?`) with which calibrations (and their ages at the start) and how many
//! retries it took. Read from the run folder alone (manifest, results, the bench file's copy).

use super::figures::waveform_of;
use crate::campaign::manifest::Manifest;
use crate::campaign::results::false_targets;
use crate::campaign::Results;
use crate::physics::C0;
use std::path::Path;

/// One fact of the summary: its name, its text, and whether it is bad news (drawn marked).
pub(crate) struct Fact {
    pub name: &'static str,
    pub text: String,
    pub alarm: bool,
}

/// The summary: a verdict line and the facts under it.
pub(crate) struct Summary {
    /// `Some(true)`: every nominal target found within the bound; `None`: no step names targets.
    pub pass: Option<bool>,
    pub verdict: String,
    pub facts: Vec<Fact>,
}

/// The worst |error| over the steps: (error m, step, algorithm).
type Worst = Option<(f64, usize, String)>;

/// Builds the summary of the run folder `dir`.
pub(crate) fn summary(dir: &Path, manifest: &Manifest, results: &Results) -> Summary {
    let mut worst: Worst = None;
    let (mut out_of_bound, mut missed, mut judged) = (Vec::new(), 0usize, 0usize);
    let mut bounds: Vec<f64> = Vec::new();
    let mut false_at: Vec<String> = Vec::new();
    let mut echoes_at: Vec<usize> = Vec::new();
    for s in &results.steps {
        let bound = waveform_of(manifest, s).map(|w| C0 / (2.0 * w.sample_rate_hz()));
        let named = !s.nominal.ranges().is_empty();
        if named {
            judged += 1;
        }
        for (name, a) in &s.algorithms {
            for r in false_targets(s, a) {
                false_at.push(format!("step {} {name} at {r:.4} m", s.index));
            }
            if !a.chain_echoes.is_empty() && !echoes_at.contains(&s.index) {
                echoes_at.push(s.index);
            }
            if !named {
                continue;
            }
            missed += a.missed;
            if let Some(e) = a.error_m {
                if worst.as_ref().is_none_or(|w| e.abs() > w.0.abs()) {
                    worst = Some((e, s.index, name.clone()));
                }
                if let Some(b) = bound {
                    if !bounds.contains(&b) {
                        bounds.push(b);
                    }
                    if e.abs() > b && !out_of_bound.contains(&s.index) {
                        out_of_bound.push(s.index);
                    }
                }
            }
        }
    }
    let bound_text = match bounds.as_slice() {
        [] => "the bound c0/(2 fs)".to_string(),
        [b] => format!("±c0/(2 fs) = {:.3} mm", b * 1e3),
        _ => "±c0/(2 fs) of each step's sample rate".to_string(),
    };
    let (pass, verdict) = if judged == 0 {
        (
            None,
            "No verdict: no step names the targets' ranges, so there is no error to judge."
                .to_string(),
        )
    } else if out_of_bound.is_empty() && missed == 0 {
        (
            Some(true),
            format!(
                "PASS: every nominal target of the {judged} steps found within {bound_text} \
                 (the thesis' bound, interpolated range)."
            ),
        )
    } else {
        let mut why = Vec::new();
        if !out_of_bound.is_empty() {
            why.push(format!(
                "{} step(s) past {bound_text} (steps {})",
                out_of_bound.len(),
                list(&out_of_bound)
            ));
        }
        if missed > 0 {
            why.push(format!("{missed} nominal target(s) missed"));
        }
        (Some(false), format!("FAIL: {}.", why.join("; ")))
    };
    let mut facts = vec![
        Fact {
            name: "Worst error",
            text: worst.map_or("-".into(), |(e, step, name)| {
                format!("{:+.3} mm (step {step}, {name})", e * 1e3)
            }),
            alarm: !out_of_bound.is_empty(),
        },
        Fact {
            name: "False targets",
            text: if false_at.is_empty() {
                "none".into()
            } else {
                format!("{}: {}", false_at.len(), false_at.join("; "))
            },
            alarm: !false_at.is_empty(),
        },
        Fact {
            name: "Chain echoes",
            text: if echoes_at.is_empty() {
                "none".into()
            } else {
                format!(
                    "{} step(s): {} (taken for the chain's, not targets)",
                    echoes_at.len(),
                    list(&echoes_at)
                )
            },
            alarm: false,
        },
        Fact {
            name: "Steps",
            text: format!(
                "{} of {} measured, status {}",
                results.steps.len(),
                manifest.plan.steps.len(),
                manifest.status.name()
            ),
            alarm: false,
        },
        Fact {
            name: "Date",
            text: manifest.created.clone(),
            alarm: false,
        },
        Fact {
            name: "Duration",
            text: duration(manifest),
            alarm: false,
        },
        Fact {
            name: "Operator",
            text: manifest
                .operator
                .clone()
                .unwrap_or_else(|| "not recorded".into()),
            alarm: false,
        },
    ];
    facts.extend(instruments(manifest));
    facts.push(Fact {
        name: "Calibrations",
        text: calibrations(dir, manifest),
        alarm: manifest.plan.bench.file.is_some() && !manifest.plan.bench.calibrated,
    });
    facts.push(Fact {
        name: "Retries",
        text: retries(manifest),
        alarm: false,
    });
    Summary {
        pass,
        verdict,
        facts,
    }
}

fn list(steps: &[usize]) -> String {
    steps
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The sessions' time, added up (each session's own total; the last one's end when it has none).
fn duration(manifest: &Manifest) -> String {
    let seconds: f64 = manifest
        .sessions
        .iter()
        .map(|s| {
            if s.timing.total_s > 0.0 {
                return s.timing.total_s;
            }
            let end = s.ended.as_deref().unwrap_or(&manifest.updated);
            match (
                crate::time::parse_utc(&s.started),
                crate::time::parse_utc(end),
            ) {
                (Some(a), Some(b)) if b >= a => b - a,
                _ => 0.0,
            }
        })
        .sum();
    let n = manifest.sessions.len();
    let sessions = if n == 1 {
        String::new()
    } else {
        format!(" in {n} sessions")
    };
    format!("{}{sessions}", human_duration(seconds))
}

/// `12.3 s`, `4 min 05 s`, `2 h 07 min`.
fn human_duration(s: f64) -> String {
    if s < 60.0 {
        format!("{s:.1} s")
    } else if s < 3600.0 {
        let s = s.round() as u64;
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        let m = (s / 60.0).round() as u64;
        format!("{} h {:02} min", m / 60, m % 60)
    }
}

fn instruments(manifest: &Manifest) -> Vec<Fact> {
    let Some(i) = &manifest.instruments else {
        return vec![Fact {
            name: "Instruments",
            text: "not recorded (no step reached the bench)".into(),
            alarm: false,
        }];
    };
    let mut out = vec![
        Fact {
            name: "AWG *IDN?",
            text: i.awg.clone(),
            alarm: false,
        },
        Fact {
            name: "Scope *IDN?",
            text: i.scope.clone(),
            alarm: false,
        },
    ];
    for (name, idn) in [("Tx *IDN?", &i.tx), ("Rx *IDN?", &i.rx)] {
        if let Some(idn) = idn {
            out.push(Fact {
                name,
                text: idn.clone(),
                alarm: false,
            });
        }
    }
    out
}

/// `measured 2026-11-21T20:00:00.000Z, 3.2 days before the run`.
fn measured(at: &str, start: &str) -> String {
    match (crate::time::parse_utc(at), crate::time::parse_utc(start)) {
        (Some(a), Some(s)) => {
            let days = (s - a) / 86_400.0;
            let age = if days.abs() < 1.0 {
                format!("{:.1} h", days * 24.0)
            } else {
                format!("{days:.1} days")
            };
            format!("measured {at}, {age} before the run")
        }
        _ => format!("measured {at}"),
    }
}

fn calibrations(dir: &Path, manifest: &Manifest) -> String {
    let mut parts = Vec::new();
    let plan = &manifest.plan;
    if plan.bench.file.is_none() {
        parts.push(format!(
            "the built-in mock lab's nominal system delay ({:.3} ns)",
            plan.bench.system_delay_s * 1e9
        ));
    } else if plan.bench.calibrated {
        // The bench file's copy in the run folder holds when its delay was measured.
        let at = manifest
            .bench_file
            .as_ref()
            .and_then(|b| {
                std::fs::read_to_string(dir.join(&b.copy))
                    .ok()
                    .map(|t| (t, b))
            })
            .and_then(|(t, b)| crate::measure::BenchFile::parse(&t, &b.path).ok())
            .and_then(|f| f.calibration.and_then(|c| c.measured_at));
        parts.push(format!(
            "system delay {:.3} ns ({})",
            plan.bench.system_delay_s * 1e9,
            at.map_or("when it was measured is not recorded".into(), |a| measured(
                &a,
                &manifest.created
            ))
        ));
    } else {
        parts.push("none: the bench is not calibrated (system delay 0)".into());
    }
    if let Some(c) = &manifest.calibration {
        parts.push(format!(
            "response calibration {} ({}, {})",
            c.path.display(),
            c.mode,
            measured(&c.measured_at, &manifest.created)
        ));
    }
    parts.join("; ")
}

fn retries(manifest: &Manifest) -> String {
    let r = &manifest.retries;
    if r.is_empty() {
        return "none".into();
    }
    let mut steps: Vec<usize> = r.iter().map(|x| x.step).collect();
    steps.dedup();
    format!(
        "{} (steps {}; the Retries table lists each)",
        r.len(),
        list(&steps)
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn durations_read_as_a_person_says_them() {
        assert_eq!(super::human_duration(12.34), "12.3 s");
        assert_eq!(super::human_duration(245.0), "4 min 05 s");
        assert_eq!(super::human_duration(7620.0), "2 h 07 min");
    }
}
