//! `dynaclay devices`: what is connected, what cannot be opened, and which vendor haptic
//! libraries (OpenHaptics, Force Dimension) load.

use super::error::CliError;

/// Prints the connected devices and any permission notes.
///
/// # Errors
/// Never fails on an empty list; enumeration problems are printed as notes.
pub fn list() -> Result<(), CliError> {
    let (devices, notes) = dynaclay_devices::enumerate::list_all();
    print!("{}", dynaclay_devices::enumerate::report(&devices, &notes));
    let libraries = dynaclay_devices::enumerate::vendor_libraries();
    print!("{}", dynaclay_devices::enumerate::vendor_report(&libraries));
    println!("(the simulated arm is always available as --device sim)");
    Ok(())
}
