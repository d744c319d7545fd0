//! The demo's child processes: started with their output kept or dropped, watched for an
//! early exit, and stopped.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

/// The child processes, stopped (SIGTERM, then SIGKILL) when dropped.
#[derive(Default)]
pub struct Processes {
    children: Vec<(String, Child)>,
}

impl Processes {
    /// Starts `photopose <command> <args…> <common…>`; with `watch`, its last stdout line
    /// is kept in the returned slot.
    pub fn spawn(
        &mut self,
        exe: &Path,
        command: &str,
        args: &[&[&str]],
        common: &[String],
        watch: bool,
    ) -> Result<Option<Arc<Mutex<String>>>> {
        let mut cmd = Command::new(exe);
        cmd.arg(command).args(args.iter().flat_map(|a| a.iter())).args(common);
        if std::env::var_os("RUST_LOG").is_none() {
            cmd.env("RUST_LOG", "warn");
        }
        cmd.stdin(Stdio::null())
            .stdout(if watch { Stdio::piped() } else { Stdio::null() });
        let mut child = cmd
            .spawn()
            .with_context(|| format!("cannot start photopose {command}"))?;
        let slot = match child.stdout.take() {
            Some(out) => {
                let slot = Arc::new(Mutex::new(String::new()));
                let writer = slot.clone();
                std::thread::Builder::new()
                    .name(format!("photopose-demo-{command}"))
                    .spawn(move || {
                        for line in BufReader::new(out).lines().map_while(Result::ok) {
                            if let Ok(mut s) = writer.lock() {
                                *s = line;
                            }
                        }
                    })
                    .context("cannot start a reader thread")?;
                Some(slot)
            }
            None => None,
        };
        self.children.push((command.to_string(), child));
        Ok(slot)
    }

    /// The name of a child that has exited, if any, and how it exited.
    pub fn exited(&mut self) -> Option<(String, std::process::ExitStatus)> {
        self.children.iter_mut().find_map(|(name, c)| match c.try_wait() {
            Ok(Some(status)) => Some((name.clone(), status)),
            _ => None,
        })
    }

    /// Asks every child to terminate, waits up to 3 s, then kills what is left.
    pub fn stop(&mut self) {
        for (_, c) in &self.children {
            // SAFETY: sending a signal to a child process id we own has no memory effects.
            unsafe { libc::kill(c.id() as libc::pid_t, libc::SIGTERM) };
        }
        let deadline = Instant::now() + Duration::from_secs(3);
        for (name, c) in &mut self.children {
            while Instant::now() < deadline {
                if let Ok(Some(_)) = c.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            if let Ok(None) = c.try_wait() {
                tracing::warn!("photopose {name} did not stop; killing it");
                let _ = c.kill();
                let _ = c.wait();
            }
        }
        self.children.clear();
    }
}

impl Drop for Processes {
    fn drop(&mut self) {
        self.stop();
    }
}
