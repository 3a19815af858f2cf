//! What cameras this machine has: V4L2 nodes (with their formats when built with `v4l`),
//! USB video-class cameras and known stereo-camera vendors (through libusb with `usb`,
//! else sysfs), and FireWire cameras (through libdc1394 with `dc1394`, else sysfs).
//! A machine without any gives an empty list; problems along the way become notes.

use std::path::Path;

use crate::device_list::STEREO_VENDORS;
pub use crate::device_list::{DeviceList, FirewireDevice, UsbDevice, V4l2Device};
use crate::Result;

/// USB interface class of video devices (UVC).
const USB_CLASS_VIDEO: u8 = 0x0e;

/// Lists the cameras of this machine.
pub fn list_devices() -> Result<DeviceList> {
    let mut list =
        DeviceList { v4l2: scan_v4l2(Path::new("/dev"), Path::new("/sys/class/video4linux")), ..Default::default() };
    #[cfg(feature = "v4l")]
    for d in &mut list.v4l2 {
        match crate::v4l2::describe_formats(&d.path) {
            Ok(formats) => d.formats = formats,
            Err(e) => list.notes.push(e.to_string()),
        }
    }
    list_usb(&mut list);
    list_firewire(&mut list);
    Ok(list)
}

/// The `videoN` nodes under `dev`, numerically ordered, named from `sys`.
fn scan_v4l2(dev: &Path, sys: &Path) -> Vec<V4l2Device> {
    let Ok(entries) = std::fs::read_dir(dev) else { return Vec::new() };
    let mut found: Vec<(u32, V4l2Device)> = entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let n: u32 = name.strip_prefix("video")?.parse().ok()?;
            let label = read_trimmed(&sys.join(&name).join("name"));
            Some((n, V4l2Device { path: e.path(), name: label, formats: Vec::new() }))
        })
        .collect();
    found.sort_by_key(|(n, _)| *n);
    found.into_iter().map(|(_, d)| d).collect()
}

#[cfg(feature = "usb")]
fn list_usb(list: &mut DeviceList) {
    use rusb::UsbContext;
    let context = match rusb::Context::new() {
        Ok(c) => c,
        Err(e) => {
            list.notes.push(format!("USB: libusb could not start ({e}); USB cameras not listed"));
            return;
        }
    };
    let devices = match context.devices() {
        Ok(d) => d,
        Err(e) => {
            list.notes.push(format!("USB: devices could not be listed ({e})"));
            return;
        }
    };
    for device in devices.iter() {
        let Ok(desc) = device.device_descriptor() else { continue };
        let video_class = (0..desc.num_configurations()).any(|i| {
            device
                .config_descriptor(i)
                .is_ok_and(|c| c.interfaces().any(|itf| itf.descriptors().any(|d| d.class_code() == USB_CLASS_VIDEO)))
        });
        if !video_class && !is_stereo_vendor(desc.vendor_id()) {
            continue;
        }
        // Reading the product string needs the device opened, which may be refused.
        let product = device.open().ok().and_then(|h| h.read_product_string_ascii(&desc).ok());
        list.usb.push(UsbDevice {
            bus: device.bus_number(),
            address: device.address(),
            vendor_id: desc.vendor_id(),
            product_id: desc.product_id(),
            video_class,
            product,
        });
    }
}

#[cfg(not(feature = "usb"))]
fn list_usb(list: &mut DeviceList) {
    list.usb = scan_usb_sysfs(Path::new("/sys/bus/usb/devices"));
}

/// USB cameras from a sysfs `bus/usb/devices` folder: devices with a video-class
/// interface or from a stereo-camera vendor.
#[cfg(any(test, not(feature = "usb")))]
fn scan_usb_sysfs(dir: &Path) -> Vec<UsbDevice> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let names: Vec<String> = entries.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
    let mut found = Vec::new();
    for name in names.iter().filter(|n| !n.contains(':')) {
        let d = dir.join(name);
        let hex = |f: &str| read_trimmed(&d.join(f)).and_then(|s| u16::from_str_radix(&s, 16).ok());
        let dec = |f: &str| read_trimmed(&d.join(f)).and_then(|s| s.parse::<u8>().ok());
        let (Some(vendor_id), Some(product_id)) = (hex("idVendor"), hex("idProduct")) else { continue };
        let prefix = format!("{name}:");
        let video_class = names.iter().filter(|n| n.starts_with(&prefix)).any(|itf| {
            read_trimmed(&dir.join(itf).join("bInterfaceClass"))
                .and_then(|s| u8::from_str_radix(&s, 16).ok())
                .is_some_and(|c| c == USB_CLASS_VIDEO)
        });
        if !video_class && !is_stereo_vendor(vendor_id) {
            continue;
        }
        found.push(UsbDevice {
            bus: dec("busnum").unwrap_or(0),
            address: dec("devnum").unwrap_or(0),
            vendor_id,
            product_id,
            video_class,
            product: read_trimmed(&d.join("product")),
        });
    }
    found.sort_by_key(|d| (d.bus, d.address));
    found
}

#[cfg(feature = "dc1394")]
fn list_firewire(list: &mut DeviceList) {
    match crate::dc1394::enumerate() {
        Ok(cams) => list.firewire = cams,
        Err(e) => list.notes.push(e.to_string()),
    }
}

#[cfg(not(feature = "dc1394"))]
fn list_firewire(list: &mut DeviceList) {
    list.firewire = scan_firewire_sysfs(Path::new("/sys/bus/firewire/devices"));
}

/// FireWire nodes other than this machine's own controller, from a sysfs
/// `bus/firewire/devices` folder.
#[cfg(any(test, not(feature = "dc1394")))]
fn scan_firewire_sysfs(dir: &Path) -> Vec<FirewireDevice> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut found: Vec<FirewireDevice> = entries
        .flatten()
        .filter_map(|e| {
            let d = e.path();
            // Units (fw1.0) repeat their node; the local controller is no camera.
            if e.file_name().to_string_lossy().contains('.')
                || read_trimmed(&d.join("is_local")).as_deref() == Some("1")
            {
                return None;
            }
            let guid = read_trimmed(&d.join("guid"))?;
            let guid = u64::from_str_radix(guid.trim_start_matches("0x"), 16).ok()?;
            Some(FirewireDevice {
                guid,
                vendor: read_trimmed(&d.join("vendor_name")).unwrap_or_default(),
                model: read_trimmed(&d.join("model_name")).unwrap_or_default(),
            })
        })
        .collect();
    found.sort_by_key(|d| d.guid);
    found
}

fn is_stereo_vendor(id: u16) -> bool {
    STEREO_VENDORS.iter().any(|v| v.0 == id)
}

fn read_trimmed(path: &Path) -> Option<String> {
    std::fs::read_to_string(path).ok().map(|s| s.trim().to_string()).filter(|s| !s.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(path: &Path, text: &str) {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, format!("{text}\n")).unwrap();
    }

    #[test]
    fn v4l2_nodes_are_found_in_number_order_with_names() {
        let t = tempfile::tempdir().unwrap();
        let (dev, sys) = (t.path().join("dev"), t.path().join("sys"));
        for n in [10, 2, 0] {
            write(&dev.join(format!("video{n}")), "");
        }
        write(&dev.join("videonot"), "");
        write(&dev.join("null"), "");
        write(&sys.join("video2").join("name"), "Bumblebee USB");
        let found = scan_v4l2(&dev, &sys);
        let paths: Vec<_> = found.iter().map(|d| d.path.file_name().unwrap().to_str().unwrap()).collect();
        assert_eq!(paths, ["video0", "video2", "video10"]);
        assert_eq!(found[1].name.as_deref(), Some("Bumblebee USB"));
        assert_eq!(found[0].name, None);
        assert!(scan_v4l2(&t.path().join("none"), &sys).is_empty());
    }

    #[test]
    fn usb_lists_video_class_and_stereo_vendors_only() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path();
        let device = |name: &str, vendor: &str, product: &str, bus: u8, addr: u8| {
            write(&d.join(name).join("idVendor"), vendor);
            write(&d.join(name).join("idProduct"), product);
            write(&d.join(name).join("busnum"), &bus.to_string());
            write(&d.join(name).join("devnum"), &addr.to_string());
        };
        device("1-1", "046d", "0825", 1, 4); // a UVC webcam
        write(&d.join("1-1").join("product"), "Webcam C270");
        write(&d.join("1-1:1.0").join("bInterfaceClass"), "0e");
        write(&d.join("1-1:1.2").join("bInterfaceClass"), "01");
        device("1-2", "1e10", "3300", 1, 7); // Point Grey, vendor class
        write(&d.join("1-2:1.0").join("bInterfaceClass"), "ff");
        device("2-1", "0781", "5567", 2, 2); // a USB stick
        write(&d.join("2-1:1.0").join("bInterfaceClass"), "08");
        device("usb1", "1d6b", "0002", 1, 1); // root hub
        let found = scan_usb_sysfs(d);
        assert_eq!(found.len(), 2, "{found:?}");
        assert_eq!((found[0].vendor_id, found[0].product_id, found[0].video_class), (0x046d, 0x0825, true));
        assert_eq!(found[0].product.as_deref(), Some("Webcam C270"));
        assert_eq!((found[1].vendor_id, found[1].address, found[1].video_class), (0x1e10, 7, false));
        let list = DeviceList { usb: found, ..Default::default() };
        assert!(!list.is_empty());
        assert!(list.to_string().contains("1e10:3300") && list.to_string().contains("Point Grey"), "{list}");
    }

    #[test]
    fn firewire_skips_the_local_controller_and_units() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path();
        write(&d.join("fw0").join("guid"), "0x0011060000001234");
        write(&d.join("fw0").join("is_local"), "1");
        write(&d.join("fw1").join("guid"), "0x00b09d01006fb38f");
        write(&d.join("fw1").join("is_local"), "0");
        write(&d.join("fw1").join("vendor_name"), "Point Grey Research");
        write(&d.join("fw1").join("model_name"), "Bumblebee2 BB2-08S2M");
        write(&d.join("fw1.0").join("guid"), "0x00b09d01006fb38f");
        let found = scan_firewire_sysfs(d);
        assert_eq!(
            found,
            [FirewireDevice {
                guid: 0x00b0_9d01_006f_b38f,
                vendor: "Point Grey Research".into(),
                model: "Bumblebee2 BB2-08S2M".into()
            }]
        );
    }

    #[test]
    fn listing_this_machine_does_not_fail() {
        // Whatever this machine has (often nothing), listing it is no error.
        let list = list_devices().unwrap();
        let _ = list.to_string();
    }
}
