//! The serial ports of this machine (`rigcast devices`), as the serialport crate finds them.

/// One serial port.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PortInfo {
    /// What to put in a suit's `port = ...` (`/dev/ttyUSB0`).
    pub path: String,
    /// USB (with vendor, product and serial when known), PCI, Bluetooth or unknown.
    pub kind: String,
}

/// Every serial port found, by path; an empty list when the system cannot be asked.
pub fn list_serial_ports() -> Vec<PortInfo> {
    let mut ports: Vec<PortInfo> = serialport::available_ports()
        .unwrap_or_default()
        .into_iter()
        .map(|p| PortInfo {
            path: p.port_name,
            kind: match p.port_type {
                serialport::SerialPortType::UsbPort(u) => format!(
                    "USB {:04x}:{:04x}{}{}",
                    u.vid,
                    u.pid,
                    u.product.map(|s| format!(" {s}")).unwrap_or_default(),
                    u.serial_number
                        .map(|s| format!(" (serial {s})"))
                        .unwrap_or_default()
                ),
                serialport::SerialPortType::PciPort => "PCI".into(),
                serialport::SerialPortType::BluetoothPort => "Bluetooth".into(),
                serialport::SerialPortType::Unknown => "unknown".into(),
            },
        })
        .collect();
    ports.sort_by(|a, b| a.path.cmp(&b.path));
    ports
}
