//! The cameras a machine has, by bus, as `camplace devices` lists them: the types the
//! listing (devices.rs) and the FireWire library's enumeration (dc1394.rs) both fill.

use std::fmt;
use std::path::PathBuf;

/// USB vendors that make stereo cameras, listed even when they do not say "video class".
pub(crate) const STEREO_VENDORS: [(u16, &str); 3] =
    [(0x1e10, "Point Grey / FLIR"), (0x2b03, "Stereolabs"), (0x2560, "e-con Systems")];

/// The cameras found, by bus.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DeviceList {
    /// Video4Linux2 nodes.
    pub v4l2: Vec<V4l2Device>,
    /// USB cameras.
    pub usb: Vec<UsbDevice>,
    /// FireWire cameras.
    pub firewire: Vec<FirewireDevice>,
    /// What could not be looked at, and why (a bus without permission, a missing library).
    pub notes: Vec<String>,
}

/// A Video4Linux2 node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct V4l2Device {
    /// `/dev/videoN`.
    pub path: PathBuf,
    /// The driver's name for it, from sysfs.
    pub name: Option<String>,
    /// Its capture formats as `FOURCC WxH` (empty without the `v4l` feature).
    pub formats: Vec<String>,
}

/// A USB camera.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsbDevice {
    /// USB bus number.
    pub bus: u8,
    /// Device address on the bus.
    pub address: u8,
    /// USB vendor id.
    pub vendor_id: u16,
    /// USB product id.
    pub product_id: u16,
    /// Whether it has a USB video class (UVC) interface.
    pub video_class: bool,
    /// The product as the device names itself, when readable.
    pub product: Option<String>,
}

/// A FireWire camera.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FirewireDevice {
    /// The 64-bit GUID, as `dc1394:GUID` takes it (hexadecimal).
    pub guid: u64,
    /// Maker, as the camera names it.
    pub vendor: String,
    /// Model, as the camera names it.
    pub model: String,
}

impl DeviceList {
    /// Whether no camera was found on any bus.
    pub fn is_empty(&self) -> bool {
        self.v4l2.is_empty() && self.usb.is_empty() && self.firewire.is_empty()
    }
}

impl fmt::Display for DeviceList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for d in &self.v4l2 {
            write!(f, "v4l2      {}  {}", d.path.display(), d.name.as_deref().unwrap_or("?"))?;
            if !d.formats.is_empty() {
                write!(f, "  [{}]", d.formats.join(", "))?;
            }
            writeln!(f)?;
        }
        for d in &self.usb {
            let vendor = STEREO_VENDORS.iter().find(|v| v.0 == d.vendor_id).map_or("", |v| v.1);
            writeln!(
                f,
                "usb       bus {:03} device {:03}  {:04x}:{:04x}  {}{}{}",
                d.bus,
                d.address,
                d.vendor_id,
                d.product_id,
                d.product.as_deref().unwrap_or(""),
                if vendor.is_empty() { "" } else { "  " },
                vendor,
            )?;
        }
        for d in &self.firewire {
            writeln!(f, "firewire  dc1394:{:016x}  {} {}", d.guid, d.vendor, d.model)?;
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        Ok(())
    }
}
