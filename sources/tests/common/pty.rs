//! Test helpers shared by the serial tests of two crates (`sources/tests/live_serial.rs`,
//! `server/tests/calibrate_cli.rs`, which includes this file by path): a raw-mode
//! pseudo-terminal standing in for a suit's serial port, and the rotation angle they judge by.

use std::os::unix::io::RawFd;
use std::path::PathBuf;

use glam::Quat;

/// Angle between rotations, accurate for tiny angles.
pub fn angle(a: Quat, b: Quat) -> f32 {
    let d = a.inverse() * b;
    2.0 * d.xyz().length().atan2(d.w.abs())
}

/// A pseudo-terminal pair; the source opens `path` (the slave), the test writes to `master`.
pub struct Pty {
    pub master: RawFd,
    pub slave: RawFd,
    pub path: PathBuf,
}

impl Pty {
    pub fn new() -> Pty {
        let r = nix::pty::openpty(None, None).unwrap();
        // Raw mode, so binary frames pass unchanged (no CR/LF translation, no echo).
        let mut t = nix::sys::termios::tcgetattr(r.slave).unwrap();
        nix::sys::termios::cfmakeraw(&mut t);
        nix::sys::termios::tcsetattr(r.slave, nix::sys::termios::SetArg::TCSANOW, &t).unwrap();
        let path = nix::unistd::ttyname(r.slave).unwrap();
        Pty {
            master: r.master,
            slave: r.slave,
            path,
        }
    }

    /// Writes all of `bytes` to the master side.
    #[allow(dead_code)]
    pub fn write(&self, bytes: &[u8]) {
        let mut rest = bytes;
        while !rest.is_empty() {
            let n = nix::unistd::write(self.master, rest).unwrap();
            rest = &rest[n..];
        }
    }
}

impl Drop for Pty {
    fn drop(&mut self) {
        let _ = nix::unistd::close(self.master);
        let _ = nix::unistd::close(self.slave);
    }
}
