//! `dynaclay devices`: what is connected, and what cannot be opened.

use super::error::CliError;

/// Prints the connected devices and any permission notes.
///
/// # Errors
/// Never fails on an empty list; enumeration problems are printed as notes.
pub fn list() -> Result<(), CliError> {
    let (devices, notes) = dynaclay_devices::enumerate::list_all();
    print!("{}", dynaclay_devices::enumerate::report(&devices, &notes));
    println!("(the simulated arm is always available as --device sim)");
    Ok(())
}
