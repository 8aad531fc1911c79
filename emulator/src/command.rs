//! The QEMU command line of the emulated board.

use std::path::Path;
use std::process::Command;

use crate::QEMU;

/// The machine: an Arm MPS2 board with the AN386 image, a Cortex-M4 with an FPU.
const MACHINE: &str = "mps2-an386";
const CPU: &str = "cortex-m4";

/// The program's name, the first semihosting argument, as in C's argv: without any `arg=`, QEMU
/// would pass the kernel's path in its place.
const PROGRAM_NAME: &str = "feeder-firmware";

/// `-icount shift=ICOUNT_SHIFT`: every instruction advances virtual time by 2^shift ns, so a run
/// is deterministic and its timer cycles count instructions.
pub const ICOUNT_SHIFT: u32 = feeder_shared::scenario::QEMU_ICOUNT_SHIFT;

/// Virtual time per instruction under [`ICOUNT_SHIFT`], in nanoseconds.
pub const NS_PER_INSTRUCTION: u32 = 1 << ICOUNT_SHIFT;

/// Where QEMU connects the board's UART0 (the serial console of the console image) and UART1
/// (its Modbus RTU port).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Serial {
    /// Not connected: the scripted image has no console.
    None,
    /// The console on a TCP server on this loopback port that a client may connect to at any
    /// time; the Modbus port not connected.
    Tcp { port: u16 },
    /// The console and the Modbus port each on a TCP server on loopback: a Modbus master
    /// connects to `modbus` and speaks RTU frames over it.
    Lines { console: u16, modbus: u16 },
}

impl Serial {
    /// The `-serial` backends, UART0's first. The Modbus port's sends each byte at once
    /// (`nodelay`): QEMU writes an answer a byte at a time, and with Nagle's algorithm a client's
    /// delayed acknowledgement of the first byte would hold the rest back by up to 40 ms, longer
    /// than a Modbus master waits between a request's bytes and far longer than a real line
    /// takes.
    fn backends(self) -> Vec<String> {
        let tcp = |port: u16| format!("tcp:127.0.0.1:{port},server=on,wait=off");
        match self {
            Serial::None => vec!["none".into()],
            Serial::Tcp { port } => vec![tcp(port)],
            Serial::Lines { console, modbus } => {
                vec![tcp(console), format!("{},nodelay=on", tcp(modbus))]
            }
        }
    }
}

/// QEMU running `elf` with the scenario words (`key=value`) as its command line and UART0 on
/// `serial`; the firmware's defmt output appears on QEMU's standard output.
pub fn command<S: AsRef<str>>(elf: &Path, scenario: &[S], serial: Serial) -> Command {
    let mut command = Command::new(QEMU);
    command
        .args(["-machine", MACHINE, "-cpu", CPU])
        .args(["-display", "none", "-monitor", "none"]);
    for backend in serial.backends() {
        command.args(["-serial", &backend]);
    }
    command
        .args(["-semihosting-config", &semihosting(scenario)])
        .args(["-icount", &format!("shift={ICOUNT_SHIFT}")])
        .arg("-kernel")
        .arg(elf);
    command
}

/// The semihosting configuration whose arguments are the program's name and `scenario`; a comma
/// in a word is doubled, QEMU's escape for it in an option value.
fn semihosting<S: AsRef<str>>(scenario: &[S]) -> String {
    let mut config = format!("enable=on,target=native,arg={PROGRAM_NAME}");
    for word in scenario {
        config.push_str(",arg=");
        config.push_str(&word.as_ref().replace(',', ",,"));
    }
    config
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arguments(command: &Command) -> Vec<String> {
        command
            .get_args()
            .map(|argument| argument.to_string_lossy().into_owned())
            .collect()
    }

    #[test]
    fn a_scripted_run_has_no_serial_and_its_words_after_the_program_name() {
        let command = command(Path::new("fw.elf"), &["cycles=20", "ramp=4"], Serial::None);
        assert_eq!(command.get_program(), QEMU);
        assert_eq!(
            arguments(&command),
            [
                "-machine",
                "mps2-an386",
                "-cpu",
                "cortex-m4",
                "-display",
                "none",
                "-monitor",
                "none",
                "-serial",
                "none",
                "-semihosting-config",
                "enable=on,target=native,arg=feeder-firmware,arg=cycles=20,arg=ramp=4",
                "-icount",
                "shift=4",
                "-kernel",
                "fw.elf",
            ]
        );
    }

    #[test]
    fn the_console_listens_on_loopback_without_waiting_for_a_client() {
        let command = command(
            Path::new("fw.elf"),
            &[] as &[&str],
            Serial::Tcp { port: 4444 },
        );
        let arguments = arguments(&command);
        let serial = arguments.iter().position(|a| a == "-serial").unwrap();
        assert_eq!(
            arguments[serial + 1],
            "tcp:127.0.0.1:4444,server=on,wait=off"
        );
    }

    #[test]
    fn the_modbus_port_is_the_second_serial_backend() {
        let command = command(
            Path::new("fw.elf"),
            &[] as &[&str],
            Serial::Lines {
                console: 4444,
                modbus: 5020,
            },
        );
        let arguments = arguments(&command);
        let backends: Vec<&String> = arguments
            .iter()
            .zip(arguments.iter().skip(1))
            .filter(|(flag, _)| *flag == "-serial")
            .map(|(_, backend)| backend)
            .collect();
        assert_eq!(
            backends,
            [
                "tcp:127.0.0.1:4444,server=on,wait=off",
                "tcp:127.0.0.1:5020,server=on,wait=off,nodelay=on"
            ]
        );
    }

    #[test]
    fn a_comma_in_a_word_stays_inside_that_word() {
        assert_eq!(
            semihosting(&["a,b"]),
            "enable=on,target=native,arg=feeder-firmware,arg=a,,b"
        );
    }

    #[test]
    fn an_instruction_is_16_ns() {
        assert_eq!(NS_PER_INSTRUCTION, 16);
    }
}
