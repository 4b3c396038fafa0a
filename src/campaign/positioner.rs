//! Who places the targets before a step: the mock lab (the targets stood in the step's simulated
//! scene, which the runner sets), the operator at a prompt, or a program (a linear stage's script).
//!
//! A positioner runs only between measurements, when the bench is in its safe state: nothing
//! radiates while the operator's hands are near the antennas or a stage moves. A stop signal
//! ends the wait at once (the program is killed).

use super::error::CampaignError;
use super::plan::{substitute, Nominal, PositionerPlan};
use super::spec::PositionerKind;
use crate::measure::bench::scene_control::{Scene, Target};
use crate::measure::Interrupt;
use std::io::BufRead;
use std::path::PathBuf;
use std::process::Stdio;
use std::time::Duration;
use tokio::sync::mpsc;

/// Lines typed by the operator, read on a thread of their own (a blocking read of standard input
/// cannot be cancelled; the thread simply ends with the process).
pub struct LineSource {
    rx: mpsc::Receiver<Option<String>>,
}

impl LineSource {
    /// Reads `reader` line by line; the end of input is delivered as `None`.
    pub fn spawn(reader: impl BufRead + Send + 'static) -> LineSource {
        let (tx, rx) = mpsc::channel(4);
        std::thread::spawn(move || {
            let mut reader = reader;
            loop {
                let mut line = String::new();
                let item = match reader.read_line(&mut line) {
                    Ok(0) | Err(_) => None,
                    Ok(_) => Some(line.trim_end_matches(['\r', '\n']).to_string()),
                };
                let end = item.is_none();
                if tx.blocking_send(item).is_err() || end {
                    break;
                }
            }
        });
        LineSource { rx }
    }

    /// Standard input.
    pub fn stdin() -> LineSource {
        Self::spawn(std::io::BufReader::new(std::io::stdin()))
    }

    async fn next(&mut self) -> Option<String> {
        self.rx.recv().await.flatten()
    }
}

/// The campaign's positioner.
pub(crate) struct Positioner {
    plan: PositionerPlan,
    input: Option<LineSource>,
    /// Where prompts go (standard error in the CLI, so standard output keeps its JSON).
    prompt_out: Box<dyn std::io::Write + Send>,
}

impl Positioner {
    /// A positioner of `plan`; `input` feeds the prompt (standard input when `None`).
    pub(crate) fn new(plan: PositionerPlan, input: Option<LineSource>) -> Positioner {
        Positioner {
            plan,
            input,
            prompt_out: Box::new(std::io::stderr()),
        }
    }

    /// Places the targets at `ranges` for step `step` of `of`. The mock lab's targets stand in the
    /// step's scene ([`Positioner::place_in_scene`]); this waits for the operator or runs the
    /// program.
    pub(crate) async fn place(
        &mut self,
        ranges: &[f64],
        step: usize,
        of: usize,
        interrupt: &Interrupt,
    ) -> Result<(), CampaignError> {
        match self.plan.kind {
            PositionerKind::MockLab => {}
            PositionerKind::Prompt => self.prompt(ranges, step, of, interrupt).await?,
            PositionerKind::Command => self.command(ranges, step, of, interrupt).await?,
        }
        if self.plan.settle_s > 0.0 {
            let settle = Duration::from_secs_f64(self.plan.settle_s);
            tokio::select! {
                () = tokio::time::sleep(settle) => {}
                s = interrupt.wait() => return Err(CampaignError::Interrupted {
                    signal: s,
                    where_: format!("while the targets of step {step} settled; RF was off"),
                }),
            }
        }
        Ok(())
    }

    /// Whether this positioner places targets on the bench itself (the operator, a program),
    /// rather than in the simulated scene.
    pub(crate) fn places_real_targets(&self) -> bool {
        self.plan.kind != PositionerKind::MockLab
    }

    /// The simulated `scene` with the targets where this positioner puts them for a step at
    /// `nominal`: the mock lab's positioner stands the step's targets in the scene (each keeps
    /// the amplitude of the scene's target of its index, or of its last); the operator and a
    /// program move real targets, and leave the scene as it is.
    pub(crate) fn place_in_scene(&self, nominal: &Nominal, scene: &mut Scene) {
        if self.plan.kind != PositionerKind::MockLab || nominal.targets.is_empty() {
            return;
        }
        let amplitude = |i: usize| {
            scene
                .targets
                .get(i)
                .or(scene.targets.last())
                .map_or(0.5, |t| t.amplitude)
        };
        scene.targets = nominal
            .targets
            .iter()
            .enumerate()
            .map(|(i, t)| Target {
                range_m: t.range_m,
                amplitude: amplitude(i),
                velocity_mps: nominal.velocity_mps.unwrap_or(0.0),
            })
            .collect();
    }

    async fn prompt(
        &mut self,
        ranges: &[f64],
        step: usize,
        of: usize,
        interrupt: &Interrupt,
    ) -> Result<(), CampaignError> {
        let places: Vec<String> = ranges
            .iter()
            .enumerate()
            .map(|(i, r)| format!("target {} at {r:.4} m", i + 1))
            .collect();
        let _ = writeln!(
            self.prompt_out,
            "step {step}/{of}: RF is off. Place {}, then press Enter (q and Enter stops the \
             campaign; resume it later)",
            places.join(", ")
        );
        let _ = self.prompt_out.flush();
        let input = self.input.get_or_insert_with(LineSource::stdin);
        tokio::select! {
            line = input.next() => match line {
                None => Err(CampaignError::OperatorStopped {
                    why: format!("end of input before step {step}"),
                }),
                Some(l) if l.trim().eq_ignore_ascii_case("q") => Err(CampaignError::OperatorStopped {
                    why: format!("q before step {step}"),
                }),
                Some(_) => Ok(()),
            },
            s = interrupt.wait() => Err(CampaignError::Interrupted {
                signal: s,
                where_: format!("at the positioner prompt of step {step}; RF was off"),
            }),
        }
    }

    async fn command(
        &mut self,
        ranges: &[f64],
        step: usize,
        of: usize,
        interrupt: &Interrupt,
    ) -> Result<(), CampaignError> {
        let program = self.plan.program.clone().unwrap_or_default();
        let workdir = self
            .plan
            .workdir
            .clone()
            .unwrap_or_else(|| PathBuf::from("."));
        // A path (with a slash) is relative to the spec's folder; a bare name is looked up on PATH.
        let exe = if program.contains('/') {
            workdir.join(&program)
        } else {
            PathBuf::from(&program)
        };
        let args = substitute(&self.plan.args, ranges, step, of);
        let mut cmd = tokio::process::Command::new(&exe);
        cmd.args(&args)
            .current_dir(&workdir)
            .env(
                "RADBENCH_POSITION_M",
                ranges.first().map(|r| r.to_string()).unwrap_or_default(),
            )
            .env(
                "RADBENCH_POSITIONS_M",
                ranges
                    .iter()
                    .map(|r| r.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
            )
            .env("RADBENCH_STEP", step.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .kill_on_drop(true);
        own_session_and_no_other_descriptors(&mut cmd);
        let mut child = cmd
            .spawn()
            .map_err(|source| CampaignError::PositionerStart {
                program: program.clone(),
                source,
            })?;
        // Whatever way this step ends (done, failed, timed out, interrupted, an error above),
        // the program and every process it started are killed with their group.
        let group = child.id().map(ProcessGroup);
        let reader = tokio::spawn(last_bytes(child.stderr.take(), STDERR_KEPT));
        let finished = async {
            let status = child.wait().await;
            // The program is done: a child it left would hold the pipe open (and run on).
            if let Some(g) = &group {
                g.kill();
            }
            let tail = reader.await.unwrap_or_default();
            status.map(|status| (status, tail))
        };
        let timeout = Duration::from_secs_f64(self.plan.timeout_s);
        let shown = format!(
            "`{}`",
            std::iter::once(program.clone())
                .chain(args)
                .collect::<Vec<_>>()
                .join(" ")
        );
        tokio::select! {
            out = tokio::time::timeout(timeout, finished) => match out {
                Err(_) => Err(CampaignError::PositionerFailed {
                    program: shown,
                    reason: format!("did not finish within {} s (positioner.timeout_s) and was killed", self.plan.timeout_s),
                }),
                Ok(Err(e)) => Err(CampaignError::PositionerFailed {
                    program: shown,
                    reason: format!("could not be waited for: {e}"),
                }),
                Ok(Ok((status, _))) if status.success() => Ok(()),
                Ok(Ok((status, tail))) => {
                    let stderr = String::from_utf8_lossy(&tail);
                    let tail: Vec<String> = stderr
                        .lines()
                        .rev()
                        .filter(|l| !l.trim().is_empty())
                        .take(3)
                        .map(shown_line)
                        .collect();
                    let tail: Vec<String> = tail.into_iter().rev().collect();
                    Err(CampaignError::PositionerFailed {
                        program: shown,
                        reason: format!(
                            "failed ({}){}",
                            status,
                            if tail.is_empty() { String::new() } else { format!(": {}", tail.join(" | ")) }
                        ),
                    })
                }
            },
            s = interrupt.wait() => Err(CampaignError::Interrupted {
                signal: s,
                where_: format!("while the positioner moved the targets of step {step} (it was killed); RF was off"),
            }),
        }
    }
}

use std::io::Write as _;

/// The end of a positioner's standard error kept for the message; the rest is read and dropped,
/// so a program that floods it neither blocks on a full pipe nor fills radbench's memory.
const STDERR_KEPT: usize = 4096;

/// Reads `from` to its end, keeping only its last `keep` bytes.
async fn last_bytes(from: Option<tokio::process::ChildStderr>, keep: usize) -> Vec<u8> {
    use tokio::io::AsyncReadExt;
    let Some(mut from) = from else {
        return Vec::new();
    };
    let mut tail: std::collections::VecDeque<u8> = std::collections::VecDeque::with_capacity(keep);
    let mut buf = vec![0u8; 8192];
    while let Ok(n @ 1..) = from.read(&mut buf).await {
        tail.extend(&buf[..n]);
        let extra = tail.len().saturating_sub(keep);
        tail.drain(..extra);
    }
    tail.into()
}

/// One line of a positioner's standard error as a message shows it: control characters
/// dropped, at most 200 characters (the end kept: it usually says what went wrong).
fn shown_line(line: &str) -> String {
    const MAX: usize = 200;
    let clean: Vec<char> = line.chars().filter(|c| !c.is_control()).collect();
    if clean.len() <= MAX {
        clean.into_iter().collect()
    } else {
        std::iter::once('…')
            .chain(clean[clean.len() - MAX..].iter().copied())
            .collect()
    }
}

/// A positioner's process group (its program leads it): killed whole when dropped, so a child
/// the program started (a stage tool, a `sleep`) does not outlive the step.
struct ProcessGroup(u32);

impl ProcessGroup {
    fn kill(&self) {
        if let Ok(pgid) = libc::pid_t::try_from(self.0) {
            // SAFETY: kill(2) with a negative pid signals that process group; no memory involved.
            // ESRCH (the group is gone) is the normal case after a clean exit.
            unsafe {
                libc::kill(-pgid, libc::SIGKILL);
            }
        }
    }
}

impl Drop for ProcessGroup {
    fn drop(&mut self) {
        self.kill();
    }
}

/// The program starts a session (and process group) of its own, and keeps no descriptor but
/// 0-2: not radbench's sockets, nor the simulated bench's pseudo-terminals.
fn own_session_and_no_other_descriptors(cmd: &mut tokio::process::Command) {
    // Descriptors from 3 up are marked close-on-exec rather than closed: the pipe through which
    // the spawn learns whether exec worked must stay open until exec.
    const CLOSE_RANGE_CLOEXEC: u32 = 1 << 2;
    // SAFETY: the closure runs in the child between fork and exec and calls only
    // async-signal-safe functions (setsid, close_range, fcntl).
    unsafe {
        cmd.pre_exec(|| {
            if libc::setsid() < 0 {
                return Err(std::io::Error::last_os_error());
            }
            if libc::syscall(libc::SYS_close_range, 3u32, u32::MAX, CLOSE_RANGE_CLOEXEC) != 0 {
                for fd in 3..4096 {
                    libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
                }
            }
            Ok(())
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(
        kind: PositionerKind,
        program: Option<&str>,
        args: &[&str],
        timeout_s: f64,
    ) -> PositionerPlan {
        PositionerPlan {
            kind,
            program: program.map(String::from),
            args: args.iter().map(|s| s.to_string()).collect(),
            workdir: Some(std::env::temp_dir()),
            timeout_s,
            settle_s: 0.0,
        }
    }

    fn block_on<F: std::future::Future>(f: F) -> F::Output {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
            .block_on(f)
    }

    #[test]
    fn the_prompt_waits_for_a_line_and_stops_on_q_or_end_of_input() {
        block_on(async {
            let input = LineSource::spawn(std::io::Cursor::new("\nq\n"));
            let mut p = Positioner::new(plan(PositionerKind::Prompt, None, &[], 60.0), Some(input));
            p.prompt_out = Box::new(std::io::sink());
            let never = Interrupt::never();
            p.place(&[1.0], 1, 2, &never).await.unwrap();
            let err = p.place(&[0.97], 2, 2, &never).await.unwrap_err();
            assert!(
                matches!(err, CampaignError::OperatorStopped { .. }),
                "{err}"
            );
            let err = p.place(&[0.97], 2, 2, &never).await.unwrap_err();
            assert!(err.to_string().contains("end of input"), "{err}");
        });
    }

    #[test]
    fn a_command_gets_the_position_and_its_failure_stops() {
        block_on(async {
            let never = Interrupt::never();
            let mut ok = Positioner::new(
                plan(
                    PositionerKind::Command,
                    Some("sh"),
                    &["-c", "test {position_m} = 0.97 && test $RADBENCH_STEP = 2"],
                    10.0,
                ),
                None,
            );
            ok.place(&[0.97], 2, 6, &never).await.unwrap();
            let mut bad = Positioner::new(
                plan(
                    PositionerKind::Command,
                    Some("sh"),
                    &["-c", "echo stage jammed >&2; exit 3"],
                    10.0,
                ),
                None,
            );
            let err = bad.place(&[0.97], 2, 6, &never).await.unwrap_err();
            assert!(
                matches!(err, CampaignError::PositionerFailed { .. }),
                "{err}"
            );
            assert!(err.to_string().contains("stage jammed"), "{err}");
            let mut slow = Positioner::new(
                plan(PositionerKind::Command, Some("sleep"), &["30"], 0.2),
                None,
            );
            let err = slow.place(&[1.0], 1, 1, &never).await.unwrap_err();
            assert!(err.to_string().contains("killed"), "{err}");
            let mut missing = Positioner::new(
                plan(PositionerKind::Command, Some("./no-such-stage"), &[], 1.0),
                None,
            );
            let err = missing.place(&[1.0], 1, 1, &never).await.unwrap_err();
            assert!(
                matches!(err, CampaignError::PositionerStart { .. }),
                "{err}"
            );
        });
    }
}
