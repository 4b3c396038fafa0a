//! Spawned binaries in tests: every wait has a time limit, and a child still running when its
//! guard is dropped (the test failed, panicked or returned early) is killed and reaped, so no test
//! leaves a process behind.
#![allow(dead_code)]

use std::io::Read;
use std::ops::{Deref, DerefMut};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A running child, killed when dropped.
pub struct Spawned {
    child: Child,
}

impl Spawned {
    /// Spawns `command` (stdin is null unless the command set it).
    pub fn new(command: &mut Command) -> Spawned {
        let child = command
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {command:?}: {e}"));
        Spawned { child }
    }

    /// Waits for the child to end within `limit`; a child still running then is killed and the
    /// test fails.
    pub fn wait_within(&mut self, limit: Duration) -> ExitStatus {
        let deadline = Instant::now() + limit;
        loop {
            if let Some(status) = self.child.try_wait().expect("the child can be waited for") {
                return status;
            }
            if Instant::now() >= deadline {
                let _ = self.child.kill();
                let _ = self.child.wait();
                panic!("the process did not end within {limit:?}");
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The first line the child writes to its piped stdout (which it takes), within `limit`.
    pub fn first_line_within(&mut self, limit: Duration) -> String {
        let stdout = self.child.stdout.take().expect("stdout is piped");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line);
            let _ = tx.send(line);
        });
        rx.recv_timeout(limit)
            .unwrap_or_else(|_| panic!("no line on stdout within {limit:?}"))
    }

    /// Its exit status and whatever it wrote to piped stdout and stderr, within `limit`.
    pub fn output_within(mut self, limit: Duration) -> Output {
        let stdout = drain(self.child.stdout.take());
        let stderr = drain(self.child.stderr.take());
        let status = self.wait_within(limit);
        Output {
            status,
            stdout: stdout.map(joined).unwrap_or_default(),
            stderr: stderr.map(joined).unwrap_or_default(),
        }
    }
}

fn drain(pipe: Option<impl Read + Send + 'static>) -> Option<JoinHandle<Vec<u8>>> {
    pipe.map(|mut pipe| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            let _ = pipe.read_to_end(&mut bytes);
            bytes
        })
    })
}

fn joined(reader: JoinHandle<Vec<u8>>) -> Vec<u8> {
    reader.join().unwrap_or_default()
}

impl Deref for Spawned {
    type Target = Child;
    fn deref(&self) -> &Child {
        &self.child
    }
}

impl DerefMut for Spawned {
    fn deref_mut(&mut self) -> &mut Child {
        &mut self.child
    }
}

impl Drop for Spawned {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// `command.output()` with a time limit: stdin null, stdout and stderr captured.
pub fn output_within(command: &mut Command, limit: Duration) -> Output {
    command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    Spawned::new(command).output_within(limit)
}
