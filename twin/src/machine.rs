//! The machine: the core on the unicorn engine, the board's memories (flash, SRAM with its CCM
//! alias, system memory), the peripherals behind the bus, virtual time, resets, and sleeping in
//! WFI and WFE; exceptions are `exception`'s, the engine's hooks `hooks`'.

mod exception;
mod hooks;

use std::path::Path;
use std::rc::Rc;

use unicorn_engine::{uc_error, Arch, ArmCpuModel, Mode, Prot, RegisterARM, Unicorn};

use crate::image::{Hint, Image};
use crate::peripherals::scs::SCR_SEVONPEND;
use crate::peripherals::{Board, Cycles, Output};
use crate::rtt;
use crate::TwinError;
use exception::CoreFault;
use hooks::{install_hooks, move_items, EngineMemory};

/// Core cycles per instruction: the figure the firmware's segment floor assumes for code from
/// flash at four wait states behind the ART accelerator (`firmware/src/board/g474/
/// segment_timer.rs`), as a ratio.
pub const CYCLES_PER_INSTRUCTION: (u64, u64) = (3, 2);
/// Cortex-M4 exception entry and return, cycles (zero wait-state memory).
const ENTRY_CYCLES: u64 = 12;
const RETURN_CYCLES: u64 = 10;

/// Memories (RM0440, "Memory map"): flash and its boot alias, SRAM1 and SRAM2 with the CCM SRAM
/// after them (its alias at 0x2001_8000), the CCM SRAM's own address, system memory.
const FLASH: u64 = 0x0800_0000;
const FLASH_BYTES: u64 = 512 * 1024;
const SRAM: u64 = 0x2000_0000;
const SRAM12_BYTES: u64 = 96 * 1024;
const CCM: u64 = 0x1000_0000;
const CCM_ALIAS: u64 = 0x2001_8000;
const CCM_BYTES: u64 = 32 * 1024;
/// xPSR's IT bits (EPSR.IT[1:0] at 26:25, IT[7:2] at 15:10).
const XPSR_IT: u32 = 0x0600_FC00;
/// TIM4's counter (CNT), the encoder's count.
const TIM4_CNT: u32 = 0x4000_0824;
const SYSTEM_MEMORY: u64 = 0x1FFF_0000;
const SYSTEM_MEMORY_BYTES: u64 = 0x8000;
/// The flash size register in system memory (KiB) and the device's unique ID.
const FLASH_SIZE_REGISTER: u64 = 0x1FFF_75E0;
const UNIQUE_ID: u64 = 0x1FFF_7590;
/// The peripherals and the core's private peripheral bus.
const PERIPHERALS: u64 = 0x4000_0000;
const PERIPHERALS_BYTES: u64 = 0x2000_0000;
const PRIVATE: u64 = 0xE000_0000;
const PRIVATE_BYTES: u64 = 0x10_0000;
/// TIM2's auto-reload: the DAC stage's preload writes it last (`firmware/src/board/g474/dac.rs`).
const TIM2_ARR: u32 = 0x4000_002C;
/// EXC_RETURN values are fetched from here.
const EXC_RETURN_BASE: u32 = 0xFFFF_FFE0;

/// What the plate (or the bench) on the board's outputs does.
pub trait Plate {
    /// From `at` on the DAC's output holds `code`.
    fn level(&mut self, at: Cycles, code: u32);
    /// From `at` on the driver is enabled or not.
    fn enable(&mut self, at: Cycles, on: bool);
    /// The encoder's count at `at`.
    fn count(&mut self, at: Cycles) -> i32;
    /// From `at` on TIM1 drives a PWM duty of `duty_counts` on PA8 and the direction on PA9.
    fn pwm(&mut self, _at: Cycles, _duty_counts: u32, _forward: bool) {}
    /// The board resets at `at`: the driver is off (its enable's pull-down) and the analog
    /// output disconnected until the firmware drives them again.
    fn reset(&mut self, at: Cycles) {
        self.enable(at, false);
    }
}

/// Why a run stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stop {
    /// The time asked for has passed.
    Ended,
    /// The independent watchdog reset the board at `at`, `last_feed` after its last feed (it
    /// runs on from the reset).
    WatchdogReset {
        at: Cycles,
        last_feed: Option<Cycles>,
    },
}

/// Why the engine stopped a slice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SliceEnd {
    Budget,
    Hint(Hint, u32),
    Refused {
        address: u32,
        pc: u32,
        write: bool,
    },
    /// Something became pending: the machine looks for an exception to take.
    Evaluate,
    SystemReset,
    /// The engine raised a CPU exception (an undefined instruction, a breakpoint).
    CpuException(u32),
}

/// The state the engine's callbacks share.
pub struct State {
    pub board: Board,
    image: Rc<Image>,
    plate: Box<dyn Plate>,
    /// Instructions executed since power-up.
    executed: u64,
    /// The slice stops when `executed` reaches this.
    budget: u64,
    /// Cycles spent outside instructions: asleep, entering and leaving exceptions.
    extra_cycles: Cycles,
    /// The instruction being executed.
    pc: u32,
    end: Option<SliceEnd>,
    /// What a register write asked for, taken at the next instruction.
    requested: Option<SliceEnd>,
    /// The exceptions being handled, innermost last.
    active: Vec<u32>,
    /// The event register (WFE, SEV).
    event: bool,
    /// The defmt log read from RTT so far, not yet taken.
    log: Vec<u8>,
    /// The address of the last access the memory map refused.
    bad_access: Option<u32>,
    /// The core is locked up (a fault it could not take): it runs nothing until a reset.
    locked: bool,
    /// The work since the last edge, until its preload's last store.
    edge: Option<EdgeWork>,
    /// The edge with the most instructions from the edge to the next preload's last store
    /// (TIM2's ARR).
    worst_edge: EdgeWork,
    /// Instructions until an IT block is over, counting the first after it.
    pub(super) if_then_left: u8,
    /// The lowest stack pointer so far.
    pub(super) lowest_sp: u32,
    /// Edges whose work was measured.
    edges_measured: u64,
    /// Register writes kept while a trace runs: `(address, value)`, in order.
    writes: Option<Vec<(u32, u32)>>,
}

/// The work from an edge to the next preload: what decides how long it takes on the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EdgeWork {
    pub instructions: u64,
    /// Bytes of those instructions (2 or 4 each): flash lines to fetch.
    pub code_bytes: u64,
    /// Data reads from flash (constants, tables).
    pub flash_reads: u64,
}

/// Bytes the flash interface reads at once (RM0440, "Embedded flash memory": 64-bit lines).
const FLASH_LINE_BYTES: u64 = 8;

impl EdgeWork {
    /// Core cycles the work takes at most with no help from the ART accelerator: every 8-byte
    /// line of code and every data read from flash a miss of `wait_states + 1` cycles, none of
    /// it overlapped with execution, and each instruction a cycle to execute.
    pub fn cycles_without_cache(&self, wait_states: u64) -> u64 {
        let line_cycles = wait_states + 1;
        self.code_bytes.div_ceil(FLASH_LINE_BYTES) * line_cycles
            + self.flash_reads * line_cycles
            + self.instructions
    }
}

impl State {
    /// The core's time.
    pub fn now(&self) -> Cycles {
        self.extra_cycles + self.executed * CYCLES_PER_INSTRUCTION.0 / CYCLES_PER_INSTRUCTION.1
    }

    /// Before a read of `address` at `now`: where it is TIM4's count, the plate, handed the
    /// outputs so far, sets it (the core's reads and the DMA's alike).
    fn before_read(&mut self, address: u32, now: Cycles) {
        if address & !3 == TIM4_CNT {
            self.deliver_outputs();
            let count = self.plate.count(now);
            self.board.set_encoder(count as u32);
        }
    }

    /// Hands the board's output changes to the plate, in order.
    fn deliver_outputs(&mut self) {
        for output in self.board.take_outputs() {
            match output {
                Output::Dac { at, code } => self.plate.level(at, code),
                Output::Enable { at, on } => self.plate.enable(at, on),
                Output::Reset { at } => self.plate.reset(at),
                Output::Pwm {
                    at,
                    duty_counts,
                    forward,
                } => self.plate.pwm(at, duty_counts, forward),
            }
        }
    }
}

/// The twin: the engine with the board around it.
pub struct Machine<'a> {
    engine: Unicorn<'a, State>,
    image: Rc<Image>,
    /// The RTT control block, where the image has one.
    rtt_block: Option<u32>,
    /// The memory the CCM SRAM's two addresses share (kept alive for the engine).
    _ccm: Box<[u8]>,
}

fn engine_error(what: &str) -> impl Fn(unicorn_engine::uc_error) -> TwinError + '_ {
    move |error| TwinError::Engine {
        what: what.to_string(),
        problem: format!("{error:?}"),
    }
}

impl<'a> Machine<'a> {
    /// Loads `elf` into a board at power-up, with `plate` on its outputs.
    pub fn load(elf: &Path, plate: Box<dyn Plate>) -> Result<Self, TwinError> {
        let image = Rc::new(Image::load(elf)?);
        let state = State {
            board: Board::new(),
            image: image.clone(),
            plate,
            executed: 0,
            budget: 0,
            extra_cycles: 0,
            pc: 0,
            end: None,
            requested: None,
            active: Vec::new(),
            event: false,
            log: Vec::new(),
            bad_access: None,
            locked: false,
            edge: None,
            worst_edge: EdgeWork::default(),
            edges_measured: 0,
            lowest_sp: u32::MAX,
            if_then_left: 0,
            writes: None,
        };
        let mut engine = Unicorn::new_with_data(Arch::ARM, Mode::THUMB | Mode::MCLASS, state)
            .map_err(engine_error("start"))?;
        engine
            .ctl_set_cpu_model(ArmCpuModel::CORTEX_M4 as i32)
            .map_err(engine_error("select the Cortex-M4"))?;
        let mut ccm = vec![0u8; CCM_BYTES as usize].into_boxed_slice();
        {
            let map = engine_error("map memory");
            engine
                .mem_map(FLASH, FLASH_BYTES, Prot::READ | Prot::EXEC)
                .map_err(&map)?;
            engine
                .mem_map(0, FLASH_BYTES, Prot::READ | Prot::EXEC)
                .map_err(&map)?;
            engine
                .mem_map(SRAM, SRAM12_BYTES, Prot::ALL)
                .map_err(&map)?;
            // SAFETY: `ccm` outlives the engine (both are fields of the machine, the engine
            // dropped first), and no Rust reference to it is used while the engine runs.
            unsafe {
                let memory = ccm.as_mut_ptr().cast();
                engine
                    .mem_map_ptr(CCM, CCM_BYTES, Prot::ALL, memory)
                    .map_err(&map)?;
                engine
                    .mem_map_ptr(CCM_ALIAS, CCM_BYTES, Prot::ALL, memory)
                    .map_err(&map)?;
            }
            engine
                .mem_map(SYSTEM_MEMORY, SYSTEM_MEMORY_BYTES, Prot::READ)
                .map_err(&map)?;
        }
        let write = engine_error("load the image");
        for (address, bytes) in &image.segments {
            engine
                .mem_write(u64::from(*address), bytes)
                .map_err(&write)?;
            if (FLASH..FLASH + FLASH_BYTES).contains(&u64::from(*address)) {
                engine
                    .mem_write(u64::from(*address) - FLASH, bytes)
                    .map_err(&write)?;
            }
        }
        engine
            .mem_write(FLASH_SIZE_REGISTER, &512u16.to_le_bytes())
            .map_err(&write)?;
        engine
            .mem_write(UNIQUE_ID, &[0x47, 0x34, 0x37, 0x34, 0, 0, 0, 0, 1, 0, 0, 0])
            .map_err(&write)?;
        install_hooks(&mut engine)?;
        let rtt_block = image.symbol("_SEGGER_RTT");
        let mut machine = Machine {
            engine,
            image,
            rtt_block,
            _ccm: ccm,
        };
        machine.reset_core()?;
        Ok(machine)
    }

    /// The deepest the stack has reached since the image was loaded (the lowest stack pointer
    /// any instruction ran with, or an exception frame was pushed at), and its size, bytes;
    /// beyond the size it overflowed. `None` where the image does not name its stack's bounds.
    pub fn stack_use(&self) -> Option<(u32, u32)> {
        let (bottom, top) = self.image.stack()?;
        let lowest = self.engine.get_data().lowest_sp.min(top);
        Some((top.wrapping_sub(lowest), top - bottom))
    }

    /// The core's reset: SP and PC from the vector table at 0, thread mode, no exception.
    fn reset_core(&mut self) -> Result<(), TwinError> {
        let read = engine_error("read the vector table");
        let sp = self
            .read_word(0)
            .ok_or_else(|| read(unicorn_engine::uc_error::READ_UNMAPPED))?;
        let pc = self
            .read_word(4)
            .ok_or_else(|| read(unicorn_engine::uc_error::READ_UNMAPPED))?;
        let reg = engine_error("set the core's registers");
        self.engine
            .reg_write(RegisterARM::CONTROL, 0)
            .map_err(&reg)?;
        self.engine
            .reg_write(RegisterARM::PRIMASK, 0)
            .map_err(&reg)?;
        self.engine
            .reg_write(RegisterARM::FAULTMASK, 0)
            .map_err(&reg)?;
        self.engine
            .reg_write(RegisterARM::BASEPRI, 0)
            .map_err(&reg)?;
        self.engine
            .reg_write(RegisterARM::MSP, u64::from(sp))
            .map_err(&reg)?;
        self.engine
            .reg_write(RegisterARM::SP, u64::from(sp))
            .map_err(&reg)?;
        self.engine
            .reg_write(RegisterARM::LR, 0xFFFF_FFFF)
            .map_err(&reg)?;
        self.engine
            .reg_write(RegisterARM::PC, u64::from(pc & !1))
            .map_err(&reg)?;
        let state = self.engine.get_data_mut();
        state.active.clear();
        state.event = false;
        state.locked = false;
        Ok(())
    }

    /// The core's time.
    pub fn now(&self) -> Cycles {
        self.engine.get_data().now()
    }

    /// Instructions executed since power-up.
    pub fn instructions(&self) -> u64 {
        self.engine.get_data().executed
    }

    /// Presses (`true`) or releases the user button B1 (PC13, high when pressed).
    pub fn button(&mut self, pressed: bool) {
        self.engine
            .get_data_mut()
            .board
            .drive_pin(2, 13, Some(pressed));
    }

    /// Sends `bytes` to the board's console (LPUART1's RX) from now on, a frame each.
    pub fn serial_send(&mut self, bytes: &[u8]) {
        let now = self.now();
        self.engine.get_data_mut().board.serial_receive(bytes, now);
    }

    /// What the board's console has sent (LPUART1's TX) by now, since last taken.
    pub fn serial_take(&mut self) -> Vec<u8> {
        let now = self.now();
        self.engine.get_data_mut().board.serial_take(now)
    }

    /// Sends `bytes` to the board's RS-485 port (USART1's RX) from now on, a character each.
    pub fn rs485_send(&mut self, bytes: &[u8]) {
        let now = self.now();
        self.engine.get_data_mut().board.rs485_receive(bytes, now);
    }

    /// What the board has sent on its RS-485 port (USART1's TX) by now, since last taken: each
    /// byte with the time its last stop bit ended.
    pub fn rs485_take(&mut self) -> Vec<(Cycles, u8)> {
        let now = self.now();
        self.engine.get_data_mut().board.rs485_take(now)
    }

    /// Drives pin `pin` of port `port` (0 for A) from outside at `level`, `None` to release it.
    pub fn drive_pin(&mut self, port: usize, pin: u32, level: Option<bool>) {
        self.engine.get_data_mut().board.drive_pin(port, pin, level);
    }

    /// The level on pin `pin` of port `port` (0 for A) now, as the outside sees it (an output's
    /// level, USART1's driver enable on PA12).
    pub fn pin(&self, port: usize, pin: u32) -> bool {
        self.board().pin_level(port, pin, self.now())
    }

    /// The stack pointer.
    pub fn stack_pointer(&self) -> u32 {
        self.reg(RegisterARM::SP)
    }

    /// A peripheral register's value now, as the core would read it.
    pub fn register(&self, address: u32) -> Option<u32> {
        self.board().read(address, self.now()).ok()
    }

    /// Kills the edge counter: from now on (resets included) TIM3 ignores the segment timer's
    /// TRGO, as a broken internal trigger would.
    pub fn kill_edge_counter(&mut self) {
        self.engine.get_data_mut().board.edge_counter_dead = true;
    }

    /// Breaks DMA1's channel `channel` (0-based): its next move and every one after it is a
    /// transfer error, which disables the channel.
    pub fn break_dma_channel(&mut self, channel: usize) {
        self.engine.get_data_mut().board.dma_channel_broken = Some(channel);
    }

    /// Starts keeping every register write the firmware makes (dropping those kept so far).
    pub fn trace_writes(&mut self) {
        self.engine.get_data_mut().writes = Some(Vec::new());
    }

    /// The register writes kept since [`Machine::trace_writes`], `(address, value)` in order.
    pub fn traced_writes(&self) -> &[(u32, u32)] {
        self.engine.get_data().writes.as_deref().unwrap_or(&[])
    }

    /// Raises the non-maskable interrupt.
    pub fn nmi(&mut self) {
        self.engine.get_data_mut().board.scs.pend_nmi();
    }

    /// The instruction the core runs next.
    pub fn pc(&self) -> u32 {
        self.reg(RegisterARM::PC)
    }

    /// The edge with the most instructions from the edge (TIM2's update) to the store that ends
    /// the next segment's preload (TIM2's ARR), and how many edges were measured.
    pub fn edge_work(&self) -> (EdgeWork, u64) {
        let state = self.engine.get_data();
        (state.worst_edge, state.edges_measured)
    }

    /// The board's peripherals, to look at.
    pub fn board(&self) -> &Board {
        &self.engine.get_data().board
    }

    /// The defmt log bytes read from RTT since last taken.
    pub fn take_log(&mut self) -> Vec<u8> {
        self.drain_rtt();
        std::mem::take(&mut self.engine.get_data_mut().log)
    }

    /// The image's data symbols whose names hold `part`.
    pub fn symbols_containing(&self, part: &str) -> Vec<(String, u32)> {
        self.image
            .symbols_containing(part)
            .into_iter()
            .map(|(name, address)| (name.to_string(), address))
            .collect()
    }

    /// The function holding `pc`, by its symbol.
    pub fn function(&self, pc: u32) -> String {
        self.image.function(pc).to_string()
    }

    fn drain_rtt(&mut self) {
        if let Some(block) = self.rtt_block {
            let bytes = rtt::drain(&mut EngineMemory(&mut self.engine), block);
            self.engine.get_data_mut().log.extend(bytes);
        }
    }

    fn read_word(&self, address: u32) -> Option<u32> {
        let mut bytes = [0; 4];
        self.engine.mem_read(u64::from(address), &mut bytes).ok()?;
        Some(u32::from_le_bytes(bytes))
    }

    fn write_word(&mut self, address: u32, value: u32) -> Option<()> {
        self.engine
            .mem_write(u64::from(address), &value.to_le_bytes())
            .ok()
    }

    fn reg(&self, register: RegisterARM) -> u32 {
        self.engine.reg_read(register).unwrap_or(0) as u32
    }

    fn set_reg(&mut self, register: RegisterARM, value: u32) -> Result<(), TwinError> {
        self.engine
            .reg_write(register, u64::from(value))
            .map_err(engine_error("set a register"))
    }

    /// Runs until the core's time reaches `until` (or the run ends otherwise).
    pub fn run_until(&mut self, until: Cycles) -> Result<Stop, TwinError> {
        loop {
            let now = self.now();
            self.settle(now)?;
            if let Some(stop) = self.watchdog()? {
                return Ok(stop);
            }
            if now >= until {
                self.drain_rtt();
                return Ok(Stop::Ended);
            }
            if self.engine.get_data().locked {
                self.locked_until(until)?;
                continue;
            }
            if self.take_exception()? {
                continue;
            }
            self.drain_rtt();
            let next = self.board().next_event().map_or(until, |at| at.min(until));
            let cycles = next.saturating_sub(now).max(1);
            let instructions =
                (cycles * CYCLES_PER_INSTRUCTION.1).div_ceil(CYCLES_PER_INSTRUCTION.0);
            let state = self.engine.get_data_mut();
            state.budget = state.executed + instructions;
            state.end = None;
            let pc = self.reg(RegisterARM::PC);
            let result = self.engine.emu_start(u64::from(pc | 1), 1, 0, 0);
            let end = self.engine.get_data_mut().end.take();
            match (result, end) {
                (_, Some(SliceEnd::Refused { address, pc, write })) => {
                    return Err(TwinError::Unmodelled {
                        address,
                        pc,
                        function: self.function(pc),
                        write,
                    })
                }
                (_, Some(SliceEnd::Hint(hint, at))) => self.hint(hint, at, until)?,
                (_, Some(SliceEnd::SystemReset)) => self.system_reset(false)?,
                // The engine raises its own exception on a branch to EXC_RETURN; a return is the
                // twin's.
                (_, Some(SliceEnd::CpuException(_)))
                    if self.reg(RegisterARM::PC) >= EXC_RETURN_BASE =>
                {
                    let exc_return = self.reg(RegisterARM::PC) | 1;
                    self.exception_return(exc_return)?;
                }
                (_, Some(SliceEnd::CpuException(_))) => self.fault(CoreFault::Undefined)?,
                (Err(error), _) => {
                    let pc = self.reg(RegisterARM::PC);
                    if pc >= EXC_RETURN_BASE {
                        self.exception_return(pc | 1)?;
                        continue;
                    }
                    let address = self.engine.get_data_mut().bad_access.take();
                    let fault = match error {
                        uc_error::INSN_INVALID | uc_error::EXCEPTION => CoreFault::Undefined,
                        uc_error::READ_UNMAPPED
                        | uc_error::WRITE_UNMAPPED
                        | uc_error::FETCH_UNMAPPED
                        | uc_error::READ_PROT
                        | uc_error::WRITE_PROT
                        | uc_error::FETCH_PROT => CoreFault::Bus { address },
                        _ => {
                            let pc = self.engine.get_data().pc;
                            return Err(TwinError::Engine {
                                what: format!("run the code at 0x{pc:08x} ({})", self.function(pc)),
                                problem: format!("{error:?}"),
                            });
                        }
                    };
                    self.fault(fault)?;
                }
                (Ok(()), Some(SliceEnd::Budget | SliceEnd::Evaluate) | None) => {}
            }
        }
    }

    /// A locked-up core: time passes to the next event, which only a reset ends.
    fn locked_until(&mut self, until: Cycles) -> Result<(), TwinError> {
        let now = self.now();
        let Some(next) = self.board().next_event() else {
            let pc = self.reg(RegisterARM::PC);
            return Err(TwinError::LockedUp {
                pc,
                function: self.function(pc),
            });
        };
        let to = next.min(until).max(now);
        self.engine.get_data_mut().extra_cycles += to - now;
        self.settle(to)
    }

    /// Brings the board up to `now`: its events, the DMA's moves, the outputs to the plate.
    fn settle(&mut self, now: Cycles) -> Result<(), TwinError> {
        let state = self.engine.get_data_mut();
        state.board.advance(now);
        if state.board.take_edge() {
            state.edge = Some(EdgeWork::default());
        }
        move_items(&mut self.engine);
        self.engine.get_data_mut().deliver_outputs();
        Ok(())
    }

    /// A watchdog expiry resets the board.
    fn watchdog(&mut self) -> Result<Option<Stop>, TwinError> {
        if !self.board().watchdog_expired {
            return Ok(None);
        }
        let at = self.now();
        let last_feed = self.board().last_feed();
        self.system_reset(true)?;
        Ok(Some(Stop::WatchdogReset { at, last_feed }))
    }

    /// A system reset: the peripherals at their reset values, the core from its vectors; SRAM
    /// keeps its contents.
    fn system_reset(&mut self, by_watchdog: bool) -> Result<(), TwinError> {
        self.drain_rtt();
        let state = self.engine.get_data_mut();
        let now = state.now();
        state.board = state.board.reset(now, by_watchdog);
        state.deliver_outputs();
        self.reset_core()
    }

    /// WFI, WFE or SEV at `at`: the instruction done, and the core asleep until something
    /// wakes it (or `until`).
    fn hint(&mut self, hint: Hint, at: u32, until: Cycles) -> Result<(), TwinError> {
        self.set_reg(RegisterARM::PC, at + 2)?;
        let state = self.engine.get_data_mut();
        state.executed += 1;
        match hint {
            Hint::SendEvent => {
                state.event = true;
                return Ok(());
            }
            Hint::WaitForEvent if state.event => {
                state.event = false;
                return Ok(());
            }
            Hint::WaitForEvent | Hint::WaitForInterrupt => {}
        }
        loop {
            if self.wakes(hint) {
                if hint == Hint::WaitForEvent {
                    self.engine.get_data_mut().event = false;
                }
                return Ok(());
            }
            let now = self.now();
            let Some(next) = self.board().next_event() else {
                return Err(TwinError::Asleep {
                    pc: at,
                    function: self.function(at),
                });
            };
            let wake_at = next.min(until).max(now);
            self.engine.get_data_mut().extra_cycles += wake_at - now;
            self.settle(wake_at)?;
            if wake_at >= until || self.board().watchdog_expired {
                return Ok(());
            }
        }
    }

    /// Whether a pending exception wakes the core from `hint`: one that would preempt with
    /// PRIMASK clear, or for WFE with SEVONPEND any newly pending one.
    fn wakes(&self, hint: Hint) -> bool {
        let scs = &self.board().scs;
        let Some((_, priority)) = scs.highest_pending() else {
            return self.engine.get_data().event && hint == Hint::WaitForEvent;
        };
        scs.group(priority) < scs.active_priority()
            || (hint == Hint::WaitForEvent && scs.scr() & SCR_SEVONPEND != 0)
    }
}
