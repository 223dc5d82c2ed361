//! `rigcast devices [--json]`: what a performer can pass to `--source` on this machine — the
//! cameras (index, name, modes), the serial ports, and the UDP ports of the VMC range already
//! bound (by which program), so that a `vmc:PORT` source picks a free one or the right one.

use std::collections::HashMap;
use std::ops::RangeInclusive;

use clap::Args;
use rigcast_sources::serial::ports::{list_serial_ports, PortInfo};
use rigcast_sources::vision::CameraMode;
use serde_json::json;

/// The ports VMC senders and receivers default to (39539 performer/receiver, 39540 the
/// assistant, the next ones for second instances).
pub const VMC_PORTS: RangeInclusive<u16> = 39539..=39549;

/// Options of `rigcast devices`.
#[derive(Debug, Args)]
pub struct DevicesArgs {
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// A camera as listed.
struct Camera {
    index: u32,
    name: String,
    modes: Vec<CameraMode>,
    other_formats: Vec<String>,
}

/// A bound UDP port of the VMC range.
struct UdpPort {
    address: String,
    port: u16,
    program: Option<String>,
}

/// Lists the devices.
pub fn run(args: &DevicesArgs) -> anyhow::Result<()> {
    let cameras = cameras();
    let serial = list_serial_ports();
    let udp = vmc_ports_in_use();
    if args.json {
        let doc = json!({
            "webcam_support": cfg!(feature = "webcam"),
            "cameras": cameras.iter().map(|c| json!({
                "index": c.index,
                "name": c.name,
                "modes": c.modes.iter().map(|m| json!({
                    "width": m.width, "height": m.height, "fps": m.fps,
                    "format": m.format.fourcc(),
                })).collect::<Vec<_>>(),
                "other_formats": c.other_formats,
            })).collect::<Vec<_>>(),
            "serial_ports": serial.iter().map(|p| json!({"path": p.path, "kind": p.kind}))
                .collect::<Vec<_>>(),
            "vmc_ports_in_use": udp.iter().map(|u| json!({
                "address": u.address, "port": u.port, "program": u.program,
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    print_text(&cameras, &serial, &udp);
    Ok(())
}

fn print_text(cameras: &[Camera], serial: &[PortInfo], udp: &[UdpPort]) {
    println!("cameras (--source webcam:INDEX[?width=W&height=H&fps=F&format=yuyv|mjpeg]):");
    if !cfg!(feature = "webcam") {
        println!("  (this build has no webcam support: it was built with --no-default-features)");
    } else if cameras.is_empty() {
        println!("  none (no /dev/video* capture device is present and readable)");
    }
    for c in cameras {
        println!("  {}: {}", c.index, c.name);
        for line in describe_modes(&c.modes) {
            println!("     {line}");
        }
        if !c.other_formats.is_empty() {
            println!(
                "     also {} (not decoded by rigcast)",
                c.other_formats.join(", ")
            );
        }
    }
    println!("serial ports (port = \"...\" in a suit's config, --source serial:CONFIG.toml):");
    if serial.is_empty() {
        println!("  none");
    }
    for p in serial {
        println!("  {} ({})", p.path, p.kind);
    }
    println!(
        "VMC ports in use (UDP {}-{}; --source vmc:PORT needs a free one):",
        VMC_PORTS.start(),
        VMC_PORTS.end()
    );
    if udp.is_empty() {
        println!("  none");
    }
    for u in udp {
        let who = u.program.as_deref().unwrap_or("another user's program");
        println!("  {}:{} by {who}", u.address, u.port);
    }
}

/// `MJPG 1280x720 @ 30, 60 fps` per format and size, largest first.
fn describe_modes(modes: &[CameraMode]) -> Vec<String> {
    let mut by_size: Vec<((String, u32, u32), Vec<u32>)> = Vec::new();
    for m in modes {
        let key = (m.format.fourcc().to_string(), m.width, m.height);
        match by_size.iter_mut().find(|(k, _)| *k == key) {
            Some((_, rates)) => rates.push(m.fps),
            None => by_size.push((key, vec![m.fps])),
        }
    }
    by_size.sort_by(|a, b| (&a.0 .0, b.0 .1 * b.0 .2).cmp(&(&b.0 .0, a.0 .1 * a.0 .2)));
    by_size
        .into_iter()
        .map(|((f, w, h), mut rates)| {
            rates.sort_unstable();
            rates.dedup();
            let rates: Vec<String> = rates.iter().map(u32::to_string).collect();
            format!("{f} {w}x{h} @ {} fps", rates.join(", "))
        })
        .collect()
}

#[cfg(feature = "webcam")]
fn cameras() -> Vec<Camera> {
    rigcast_sources::vision::list_cameras()
        .into_iter()
        .map(|c| Camera {
            index: c.index,
            name: c.name,
            modes: c.modes,
            other_formats: c.other_formats,
        })
        .collect()
}

#[cfg(not(feature = "webcam"))]
fn cameras() -> Vec<Camera> {
    Vec::new()
}

/// Sockets read from /proc at most (bounds the scan on a machine with very many).
const MAX_SOCKETS: usize = 1 << 16;

/// UDP sockets bound to a port of [`VMC_PORTS`] (Linux: /proc/net/udp and udp6), with the
/// program holding each when this user may see it.
fn vmc_ports_in_use() -> Vec<UdpPort> {
    let mut found: Vec<(String, u16, u64)> = Vec::new();
    for (file, v6) in [("/proc/net/udp", false), ("/proc/net/udp6", true)] {
        let Ok(text) = std::fs::read_to_string(file) else {
            continue;
        };
        for line in text.lines().skip(1).take(MAX_SOCKETS) {
            let cols: Vec<&str> = line.split_whitespace().collect();
            let (Some(local), Some(inode)) = (cols.get(1), cols.get(9)) else {
                continue;
            };
            let Some((addr, port)) = local.split_once(':') else {
                continue;
            };
            let Ok(port) = u16::from_str_radix(port, 16) else {
                continue;
            };
            if VMC_PORTS.contains(&port) {
                found.push((show_address(addr, v6), port, inode.parse().unwrap_or(0)));
            }
        }
    }
    let owners = if found.is_empty() {
        HashMap::new()
    } else {
        socket_owners()
    };
    found.sort();
    found
        .into_iter()
        .map(|(address, port, inode)| UdpPort {
            address,
            port,
            program: owners.get(&inode).cloned(),
        })
        .collect()
}

/// /proc's hex address as text (IPv4 little-endian words; IPv6 shown as `[...]`).
fn show_address(hex: &str, v6: bool) -> String {
    if !v6 {
        if let Ok(n) = u32::from_str_radix(hex, 16) {
            return std::net::Ipv4Addr::from(n.swap_bytes()).to_string();
        }
        return hex.into();
    }
    let mut bytes = [0u8; 16];
    for (i, chunk) in bytes.chunks_mut(4).enumerate() {
        let word = hex
            .get(i * 8..i * 8 + 8)
            .and_then(|w| u32::from_str_radix(w, 16).ok())
            .unwrap_or(0);
        chunk.copy_from_slice(&word.swap_bytes().to_be_bytes());
    }
    format!("[{}]", std::net::Ipv6Addr::from(bytes))
}

/// Socket inode -> `name (pid N)` for the processes whose descriptors this user may read.
fn socket_owners() -> HashMap<u64, String> {
    let mut owners = HashMap::new();
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return owners;
    };
    let mut seen = 0usize;
    for p in procs.flatten() {
        let Some(pid) = p.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else {
            continue;
        };
        let Ok(fds) = std::fs::read_dir(p.path().join("fd")) else {
            continue;
        };
        let name = std::fs::read_to_string(p.path().join("comm")).unwrap_or_default();
        for fd in fds.flatten() {
            seen += 1;
            if seen > MAX_SOCKETS * 4 {
                return owners;
            }
            let Ok(target) = std::fs::read_link(fd.path()) else {
                continue;
            };
            let target = target.to_string_lossy();
            if let Some(inode) = target
                .strip_prefix("socket:[")
                .and_then(|s| s.strip_suffix(']'))
                .and_then(|s| s.parse().ok())
            {
                owners.insert(inode, format!("{} (pid {pid})", name.trim()));
            }
        }
    }
    owners
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_addresses_read_as_text() {
        assert_eq!(show_address("0100007F", false), "127.0.0.1");
        assert_eq!(show_address("00000000", false), "0.0.0.0");
        assert_eq!(
            show_address("00000000000000000000000001000000", true),
            "[::1]"
        );
    }

    #[test]
    fn a_bound_vmc_port_is_listed_with_this_program() {
        let Ok(sock) = std::net::UdpSocket::bind(("127.0.0.1", 39549)) else {
            eprintln!("SKIP: port 39549 is taken");
            return;
        };
        let found = vmc_ports_in_use();
        let me = found
            .iter()
            .find(|u| u.port == 39549 && u.address == "127.0.0.1")
            .expect("the bound port is listed");
        let pid = std::process::id();
        assert!(
            me.program
                .as_deref()
                .is_some_and(|p| p.contains(&format!("pid {pid}"))),
            "{:?}",
            me.program
        );
        drop(sock);
    }
}
