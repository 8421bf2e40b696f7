//! Transports that carry the protocol's lines: the stdin/stdout of a child
//! process, the process's own stdin/stdout, and UDP datagrams (one line
//! each). A serial device is reached through a child process that bridges
//! it, e.g. `socat - /dev/ttyUSB0,b115200,raw,echo=0`.
//!
//! Reads that wait are done by a reader thread feeding a channel, so that
//! every transport offers the same `recv` with a timeout. The channel holds
//! a few lines only: a rig that floods the link waits for the controller
//! instead of filling its memory.
//!
//! `main` restores the default SIGPIPE (so that `mckibben … | head` ends
//! quietly), which would kill the process when it writes to a rig that has
//! exited: no message, no close, status 141. Writes to a pipe therefore run
//! with SIGPIPE blocked on the writing thread (`without_sigpipe`) and a
//! broken pipe comes back as an error the controller can report.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, UdpSocket};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::Duration;

use super::protocol::MAX_LINE;

/// What a wait for a line brought.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Received {
    /// One line, without its line break (maybe malformed: the caller parses).
    Line(String),
    /// Nothing arrived in time.
    Timeout,
    /// The other side is gone (end of stream, or the reason it broke).
    Closed(String),
}

/// A two-way line transport.
pub trait Link {
    /// Sends one line (a line break is added).
    fn send(&mut self, line: &str) -> io::Result<()>;
    /// Waits up to `timeout` (`None`: for ever) for the next line.
    fn recv(&mut self, timeout: Option<Duration>) -> Received;
    /// What the link is connected to, for messages.
    fn describe(&self) -> String;
    /// A session on the link has ended (a rig's end may accept a new peer).
    fn end_session(&mut self) {}
}

/// Lines read ahead of the controller. A rig sends one line a sample; more
/// waiting than this is a flood, held back in the rig's own pipe.
const READ_AHEAD: usize = 64;

/// Reads lines of at most [`MAX_LINE`] bytes from `reader` into a channel
/// until the stream ends. A longer line is passed on cut at the limit (plus
/// one byte), so that the parser reports it as too long.
fn spawn_reader(reader: impl Read + Send + 'static) -> Receiver<Received> {
    let (tx, rx) = mpsc::sync_channel(READ_AHEAD);
    std::thread::spawn(move || {
        let mut reader = BufReader::new(reader);
        loop {
            let mut buf = Vec::new();
            let limit = (MAX_LINE + 1) as u64;
            let msg = match (&mut reader).take(limit).read_until(b'\n', &mut buf) {
                Ok(0) => Received::Closed("end of stream".into()),
                Ok(_) => {
                    if buf.last() == Some(&b'\n') {
                        buf.pop();
                    } else if buf.len() as u64 == limit {
                        // Skip the rest of the over-long line.
                        let mut rest = Vec::new();
                        let _ = reader.read_until(b'\n', &mut rest);
                    }
                    if buf.last() == Some(&b'\r') {
                        buf.pop();
                    }
                    Received::Line(String::from_utf8_lossy(&buf).into_owned())
                }
                Err(e) => Received::Closed(e.to_string()),
            };
            let end = matches!(msg, Received::Closed(_));
            if tx.send(msg).is_err() || end {
                return;
            }
        }
    });
    rx
}

fn wait(rx: &Receiver<Received>, timeout: Option<Duration>) -> Received {
    match timeout {
        None => rx
            .recv()
            .unwrap_or_else(|_| Received::Closed("reader stopped".into())),
        Some(t) => match rx.recv_timeout(t) {
            Ok(m) => m,
            Err(RecvTimeoutError::Timeout) => Received::Timeout,
            Err(RecvTimeoutError::Disconnected) => Received::Closed("reader stopped".into()),
        },
    }
}

/// Writes `line` and a line break to `out` and flushes it, with SIGPIPE
/// held off: a reader that is gone gives an `EPIPE` error, not a signal.
fn write_line(out: &mut impl Write, line: &str) -> io::Result<()> {
    without_sigpipe(|| {
        out.write_all(line.as_bytes())?;
        out.write_all(b"\n")?;
        out.flush()
    })
}

/// Runs `f` with SIGPIPE blocked on this thread. A write to a broken pipe
/// then fails with `EPIPE` and leaves the signal pending for the thread;
/// it is taken off (`sigwait`) before the old mask returns, so it is never
/// delivered. Other threads, and this one afterwards, keep the default.
#[cfg(unix)]
fn without_sigpipe<T>(f: impl FnOnce() -> T) -> T {
    // SAFETY: the sigset_t values are initialised by sigemptyset/sigpending
    // before use; pthread_sigmask only changes this thread's mask, and the
    // old mask is restored before returning.
    unsafe {
        let mut pipe: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut pipe);
        libc::sigaddset(&mut pipe, libc::SIGPIPE);
        let mut old: libc::sigset_t = std::mem::zeroed();
        libc::pthread_sigmask(libc::SIG_BLOCK, &pipe, &mut old);
        let out = f();
        let mut pending: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut pending);
        if libc::sigpending(&mut pending) == 0
            && libc::sigismember(&pending, libc::SIGPIPE) == 1
            && libc::sigismember(&old, libc::SIGPIPE) == 0
        {
            let mut sig = 0;
            libc::sigwait(&pipe, &mut sig);
        }
        libc::pthread_sigmask(libc::SIG_SETMASK, &old, std::ptr::null_mut());
        out
    }
}

/// Without SIGPIPE there is nothing to hold off.
#[cfg(not(unix))]
fn without_sigpipe<T>(f: impl FnOnce() -> T) -> T {
    f()
}

/// A rig behind a child process's stdin and stdout (its stderr is passed
/// through). Dropping the link closes the child's stdin and reaps it.
pub struct ChildLink {
    command: String,
    child: Child,
    stdin: Option<ChildStdin>,
    rx: Receiver<Received>,
}

impl ChildLink {
    /// Starts `command` with `sh -c`.
    pub fn spawn(command: &str) -> io::Result<ChildLink> {
        let mut shell = Command::new("sh");
        shell
            .arg("-c")
            .arg(command)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        // A process group of its own: Ctrl-C in the terminal reaches the
        // controller alone, which then closes the valve through the rig; in
        // the terminal's group the rig would die with it first.
        #[cfg(unix)]
        std::os::unix::process::CommandExt::process_group(&mut shell, 0);
        let mut child = shell.spawn()?;
        let stdout = child.stdout.take().expect("piped stdout");
        let stdin = child.stdin.take();
        Ok(ChildLink {
            command: command.to_string(),
            child,
            stdin,
            rx: spawn_reader(stdout),
        })
    }
}

impl Link for ChildLink {
    fn send(&mut self, line: &str) -> io::Result<()> {
        let stdin = self
            .stdin
            .as_mut()
            .ok_or_else(|| io::Error::other("stdin closed"))?;
        write_line(stdin, line)
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Received {
        wait(&self.rx, timeout)
    }

    fn describe(&self) -> String {
        format!("`{}`", self.command)
    }
}

impl Drop for ChildLink {
    fn drop(&mut self) {
        self.stdin = None;
        // Give the rig a moment to end by itself after STOP, then make sure.
        for _ in 0..100 {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        // The whole group: `sh -c` may run the rig as a child of its own,
        // which killing the shell alone would leave running, holding the
        // inherited stderr open for whoever reads it.
        #[cfg(unix)]
        if let Ok(group) = libc::pid_t::try_from(self.child.id()) {
            // SAFETY: a plain system call; the group is the child's own
            // (`process_group(0)` in `spawn`), not yet reaped.
            unsafe {
                libc::kill(-group, libc::SIGKILL);
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// This process's own stdin and stdout (a rig served to the process that
/// started it).
pub struct StdioLink {
    rx: Receiver<Received>,
}

impl StdioLink {
    pub fn new() -> StdioLink {
        StdioLink {
            rx: spawn_reader(io::stdin()),
        }
    }
}

impl Default for StdioLink {
    fn default() -> Self {
        StdioLink::new()
    }
}

impl Link for StdioLink {
    fn send(&mut self, line: &str) -> io::Result<()> {
        write_line(&mut io::stdout().lock(), line)
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Received {
        wait(&self.rx, timeout)
    }

    fn describe(&self) -> String {
        "stdin/stdout".into()
    }
}

/// UDP: one line per datagram. The controller's end sends to a fixed peer;
/// the rig's end answers whoever sent the last `HELLO` ([`UdpLink::serve`]).
pub struct UdpLink {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    /// The rig's end: adopt the sender of a datagram as the peer.
    serving: bool,
    /// Whether the peer has sent anything yet.
    heard: bool,
}

impl UdpLink {
    /// The controller's end: an ephemeral local port talking to `peer`.
    pub fn connect(peer: SocketAddr) -> io::Result<UdpLink> {
        let local: SocketAddr = if peer.is_ipv4() {
            "0.0.0.0:0".parse().expect("address")
        } else {
            "[::]:0".parse().expect("address")
        };
        let socket = UdpSocket::bind(local)?;
        socket.connect(peer)?;
        Ok(UdpLink {
            socket,
            peer: Some(peer),
            serving: false,
            heard: false,
        })
    }

    /// The rig's end, bound to `addr`.
    pub fn serve(addr: SocketAddr) -> io::Result<UdpLink> {
        Ok(UdpLink {
            socket: UdpSocket::bind(addr)?,
            peer: None,
            serving: true,
            heard: false,
        })
    }

    /// The bound local address (to learn an ephemeral port).
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
}

impl Link for UdpLink {
    fn send(&mut self, line: &str) -> io::Result<()> {
        let peer = self
            .peer
            .ok_or_else(|| io::Error::other("no peer has spoken yet"))?;
        self.socket.send_to(line.as_bytes(), peer).map(|_| ())
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Received {
        let mut buf = vec![0u8; MAX_LINE + 2];
        // A zero timeout means "block" to the socket API.
        let timeout = timeout.map(|t| t.max(Duration::from_micros(1)));
        if let Err(e) = self.socket.set_read_timeout(timeout) {
            return Received::Closed(e.to_string());
        }
        loop {
            match self.socket.recv_from(&mut buf) {
                Ok((n, from)) => {
                    match self.peer {
                        Some(p) if p != from => continue,
                        Some(_) => {}
                        None => self.peer = Some(from),
                    }
                    self.heard = true;
                    let mut text = &buf[..n];
                    while let Some((&last, rest)) = text.split_last() {
                        if last == b'\n' || last == b'\r' {
                            text = rest;
                        } else {
                            break;
                        }
                    }
                    return Received::Line(String::from_utf8_lossy(text).into_owned());
                }
                Err(e)
                    if e.kind() == io::ErrorKind::WouldBlock
                        || e.kind() == io::ErrorKind::TimedOut =>
                {
                    return Received::Timeout;
                }
                // A datagram the peer refused (ICMP) before it ever spoke:
                // nothing listens there, and waiting would only say so
                // later and wrongly (as a timeout).
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused && !self.heard => {
                    return Received::Closed(
                        "its port refused the datagram: nothing listens there".into(),
                    );
                }
                // Once the rig has answered, a refusal is a datagram lost
                // while it restarts: silence, as the deadlines treat it.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => {
                    return Received::Timeout;
                }
                Err(e) => return Received::Closed(e.to_string()),
            }
        }
    }

    /// The rig's end forgets its peer: the next `HELLO`'s sender becomes it.
    fn end_session(&mut self) {
        if self.serving {
            self.peer = None;
        }
    }

    fn describe(&self) -> String {
        match self.peer {
            Some(p) => format!("udp {p}"),
            None => format!(
                "udp {}",
                self.socket
                    .local_addr()
                    .map_or("?".into(), |a| a.to_string())
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    /// A rig that never stops talking: an endless stream of sample lines,
    /// counting the bytes it has handed out.
    struct Flood {
        served: Arc<AtomicUsize>,
    }

    impl Read for Flood {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            const LINE: &[u8] = b"S 1 0.25 30.0\n";
            for (i, b) in buf.iter_mut().enumerate() {
                *b = LINE[(self.served.load(Ordering::Relaxed) + i) % LINE.len()];
            }
            self.served.fetch_add(buf.len(), Ordering::Relaxed);
            Ok(buf.len())
        }
    }

    #[test]
    fn a_flooding_rig_is_read_no_further_ahead_than_the_channel_holds() {
        let served = Arc::new(AtomicUsize::new(0));
        let rx = spawn_reader(Flood {
            served: served.clone(),
        });
        // The reader fills the channel, then waits for the controller.
        std::thread::sleep(Duration::from_millis(300));
        let held = served.load(Ordering::Relaxed);
        std::thread::sleep(Duration::from_millis(300));
        assert_eq!(served.load(Ordering::Relaxed), held, "still reading");
        // At most the channel's lines and the reader's buffers: a few
        // kilobytes, where an unbounded read would be megabytes by now.
        assert!(held <= 4 * 8192, "{held} bytes read ahead");
        for _ in 0..3 * READ_AHEAD {
            assert_eq!(
                wait(&rx, Some(Duration::from_secs(5))),
                Received::Line("S 1 0.25 30.0".into())
            );
        }
    }

    /// A controller whose rig address has nothing listening hears so at
    /// once: it waited nothing and then reported "no READY within 10 s".
    #[cfg(target_os = "linux")]
    #[test]
    fn a_udp_rig_that_is_not_there_is_named_not_waited_for() {
        let vacant = UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap();
        let mut link = UdpLink::connect(vacant).unwrap();
        link.send("HELLO 1").unwrap();
        match link.recv(Some(Duration::from_secs(5))) {
            Received::Closed(why) => assert!(why.contains("nothing listens there"), "{why}"),
            other => panic!("{other:?}"),
        }
    }

    /// A rig the shell runs as a child of its own ends with the link: it
    /// was left running, holding the controller's stderr open.
    #[cfg(target_os = "linux")]
    #[test]
    fn dropping_a_child_link_ends_the_rig_its_shell_started() {
        let mut link = ChildLink::spawn("sleep 30 & echo $!; wait").unwrap();
        let Received::Line(pid) = link.recv(Some(Duration::from_secs(10))) else {
            panic!("the shell did not say its child");
        };
        // Running: listed, and not a zombie waiting to be reaped.
        let running = |pid: &str| {
            std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|s| !s.contains(") Z"))
        };
        assert!(running(&pid), "{pid}");
        drop(link);
        let ended = (0..300).any(|_| {
            std::thread::sleep(Duration::from_millis(10));
            !running(&pid)
        });
        assert!(ended, "the rig {pid} outlived its link");
    }
}
