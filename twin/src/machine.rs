//! The machine: the core on the unicorn engine, the board's memories (flash, SRAM with its CCM
//! alias, system memory), the peripherals behind the bus, and what the engine leaves to the
//! harness on an M-profile core: taking exceptions (the NVIC's choice, the stack frame with the
//! FPU's extended part, EXC_RETURN), returning from them, and sleeping in WFI and WFE.

use std::path::Path;
use std::rc::Rc;

use unicorn_engine::{uc_error, Arch, ArmCpuModel, HookType, Mode, Prot, RegisterARM, Unicorn};

use crate::image::{Hint, Image};
use crate::peripherals::scs::{Request, HARD_FAULT, SCR_SEVONPEND};
use crate::peripherals::{Board, Cycles, Output};
use crate::rtt::{self, Memory};
use crate::TwinError;

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

/// A fault the core raises on an instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum CoreFault {
    /// An undefined instruction (UDF among them): a UsageFault.
    Undefined,
    /// An access the memory map refuses: a BusFault, at `address` where known.
    Bus { address: Option<u32> },
}

/// CFSR bits (ARMv7-M ARM, B3.2.15): UNDEFINSTR, PRECISERR with BFARVALID, STKERR.
const CFSR_UNDEFINSTR: u32 = 1 << 16;
const CFSR_PRECISERR: u32 = 1 << 9;
const CFSR_BFARVALID: u32 = 1 << 15;
const CFSR_STKERR: u32 = 1 << 12;

/// The core registers of an exception frame, in their order on the stack (xPSR follows).
const FRAME_REGISTERS: [RegisterARM; 7] = [
    RegisterARM::R0,
    RegisterARM::R1,
    RegisterARM::R2,
    RegisterARM::R3,
    RegisterARM::R12,
    RegisterARM::LR,
    RegisterARM::PC,
];

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
    /// Edges whose work was measured.
    edges_measured: u64,
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

    /// A fault of the instruction at the current `pc` (ARMv7-M ARM, B1.5.14): escalated to
    /// HardFault, with its cause in CFSR (and the address in BFAR); where the execution
    /// priority is already −1 or less (FAULTMASK, in HardFault or NMI), the core locks up.
    fn fault(&mut self, fault: CoreFault) -> Result<(), TwinError> {
        let pc = self.engine.get_data().pc;
        self.set_reg(RegisterARM::PC, pc)?;
        if self.execution_priority() <= -1 {
            self.engine.get_data_mut().locked = true;
            return Ok(());
        }
        let (cfsr, address) = match fault {
            CoreFault::Undefined => (CFSR_UNDEFINSTR, None),
            CoreFault::Bus { address } => (CFSR_PRECISERR | CFSR_BFARVALID, address),
        };
        self.engine
            .get_data_mut()
            .board
            .scs
            .record_fault(cfsr, address);
        self.enter(HARD_FAULT)
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

    /// The execution priority: the active exceptions', raised by PRIMASK, FAULTMASK, BASEPRI.
    fn execution_priority(&self) -> i32 {
        let scs = &self.board().scs;
        let mut priority = scs.active_priority();
        let basepri = self.reg(RegisterARM::BASEPRI) & 0xFF;
        if basepri != 0 {
            priority = priority.min(scs.group(basepri as i32));
        }
        if self.reg(RegisterARM::PRIMASK) & 1 != 0 {
            priority = priority.min(0);
        }
        if self.reg(RegisterARM::FAULTMASK) & 1 != 0 {
            priority = priority.min(-1);
        }
        priority
    }

    /// Takes the highest pending exception if it preempts what runs.
    fn take_exception(&mut self) -> Result<bool, TwinError> {
        let scs = &self.board().scs;
        let Some((number, priority)) = scs.highest_pending() else {
            return Ok(false);
        };
        if scs.group(priority) >= self.execution_priority() {
            return Ok(false);
        }
        self.enter(number)?;
        Ok(true)
    }

    /// Exception entry (ARMv7-M ARM, B1.5.6): the frame on the main stack (with the
    /// floating-point part where the thread used the FPU), EXC_RETURN in LR, the handler from
    /// the vector table.
    fn enter(&mut self, number: u32) -> Result<(), TwinError> {
        let control = self.reg(RegisterARM::CONTROL);
        let in_handler = !self.engine.get_data().active.is_empty();
        let floating = control & 4 != 0;
        if control & 2 != 0 && !in_handler {
            return Err(TwinError::Engine {
                what: "take an exception from the process stack".into(),
                problem: "the twin models the main stack only".into(),
            });
        }
        let mut frame: Vec<u32> = FRAME_REGISTERS.iter().map(|&r| self.reg(r)).collect();
        let ipsr = self.engine.get_data().active.last().copied().unwrap_or(0);
        let xpsr = (self.reg(RegisterARM::XPSR) & !0x1FF) | ipsr | 1 << 24;
        frame.push(xpsr);
        if floating {
            for index in 0..16 {
                frame.push(self.reg_s(index));
            }
            frame.push(self.reg(RegisterARM::FPSCR));
            frame.push(0);
        }
        let sp = self.reg(RegisterARM::SP);
        let mut top = sp - 4 * frame.len() as u32;
        if top & 4 != 0 {
            top -= 4;
            frame[7] |= 1 << 9;
        }
        // A frame that cannot be stacked is a bus fault on stacking (STKERR): the handler is
        // entered all the same, the stack pointer moved, the frame not written.
        let stacked = (0..frame.len() as u32).all(|index| {
            self.write_word(top + 4 * index, frame[index as usize])
                .is_some()
        });
        if !stacked {
            self.engine
                .get_data_mut()
                .board
                .scs
                .record_fault(CFSR_STKERR, None);
        }
        let vector_table = self.board().scs.vector_table();
        let handler = self.read_word(vector_table + 4 * number).unwrap_or(0);
        let exc_return = match (floating, in_handler) {
            (false, true) => 0xFFFF_FFF1,
            (false, false) => 0xFFFF_FFF9,
            (true, true) => 0xFFFF_FFE1,
            (true, false) => 0xFFFF_FFE9,
        };
        self.set_reg(RegisterARM::SP, top)?;
        self.set_reg(RegisterARM::LR, exc_return)?;
        self.set_reg(RegisterARM::CONTROL, control & !4)?;
        self.set_reg(RegisterARM::PC, handler & !1)?;
        let state = self.engine.get_data_mut();
        state.board.scs.activate(number);
        state.active.push(number);
        state.extra_cycles += ENTRY_CYCLES;
        state.event = true;
        Ok(())
    }

    /// Exception return on `exc_return` (ARMv7-M ARM, B1.5.8): the frame back off the stack,
    /// the exception no longer active.
    fn exception_return(&mut self, exc_return: u32) -> Result<(), TwinError> {
        let state = self.engine.get_data_mut();
        let Some(number) = state.active.pop() else {
            return Err(TwinError::Engine {
                what: format!("return from an exception (EXC_RETURN 0x{exc_return:08x})"),
                problem: "no exception is active".into(),
            });
        };
        state.board.scs.deactivate(number);
        state.extra_cycles += RETURN_CYCLES;
        state.event = true;
        let floating = exc_return & 0x10 == 0;
        let sp = self.reg(RegisterARM::SP);
        let words = if floating { 26 } else { 8 };
        let mut frame = Vec::with_capacity(words);
        for index in 0..words as u32 {
            frame.push(
                self.read_word(sp + 4 * index)
                    .ok_or_else(|| TwinError::Engine {
                        what: format!("unstack at 0x{sp:08x}"),
                        problem: "the stack is outside RAM".into(),
                    })?,
            );
        }
        for (register, value) in FRAME_REGISTERS.iter().zip(&frame) {
            self.set_reg(*register, *value)?;
        }
        let xpsr = frame[7];
        self.set_reg(RegisterARM::XPSR, xpsr & !0x1FF)?;
        if floating {
            for index in 0..16 {
                self.set_reg_s(index, frame[8 + index as usize])?;
            }
            self.set_reg(RegisterARM::FPSCR, frame[24])?;
        }
        let control = self.reg(RegisterARM::CONTROL);
        let control = if floating { control | 4 } else { control & !4 };
        self.set_reg(RegisterARM::CONTROL, control)?;
        let padding = if xpsr & (1 << 9) != 0 { 4 } else { 0 };
        self.set_reg(RegisterARM::SP, sp + 4 * words as u32 + padding)?;
        Ok(())
    }

    fn reg_s(&self, index: u32) -> u32 {
        self.engine
            .reg_read(RegisterARM::S0 as i32 + index as i32)
            .unwrap_or(0) as u32
    }

    fn set_reg_s(&mut self, index: u32, value: u32) -> Result<(), TwinError> {
        self.engine
            .reg_write(RegisterARM::S0 as i32 + index as i32, u64::from(value))
            .map_err(engine_error("set a floating-point register"))
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

/// The engine's memory, for the RTT reader.
struct EngineMemory<'e, 'a>(&'e mut Unicorn<'a, State>);

impl Memory for EngineMemory<'_, '_> {
    fn read_word(&self, address: u32) -> Option<u32> {
        let mut bytes = [0; 4];
        self.0.mem_read(u64::from(address), &mut bytes).ok()?;
        Some(u32::from_le_bytes(bytes))
    }

    fn read_bytes(&self, address: u32, bytes: &mut [u8]) -> Option<()> {
        self.0.mem_read(u64::from(address), bytes).ok()
    }

    fn write_word(&mut self, address: u32, value: u32) -> Option<()> {
        self.0
            .mem_write(u64::from(address), &value.to_le_bytes())
            .ok()
    }
}

/// Carries out the DMA's requested moves: each item read from its source (a register or
/// memory) and written to its destination; an address that answers neither is a transfer
/// error.
fn move_items(engine: &mut Unicorn<'_, State>) {
    loop {
        let items = engine.get_data_mut().board.take_moves();
        if items.is_empty() {
            return;
        }
        for item in items {
            let now = engine.get_data().now();
            let value = read_any(engine, item.from, item.size, now);
            let written = value.and_then(|value| write_any(engine, item.to, item.size, value, now));
            engine.get_data_mut().board.moved(&item, written.is_none());
        }
    }
}

fn is_register(address: u32) -> bool {
    (PERIPHERALS..PERIPHERALS + PERIPHERALS_BYTES).contains(&u64::from(address))
        || (PRIVATE..PRIVATE + PRIVATE_BYTES).contains(&u64::from(address))
}

fn read_any(engine: &mut Unicorn<'_, State>, address: u32, size: u32, now: Cycles) -> Option<u32> {
    if is_register(address) {
        let word = engine.get_data_mut().board.read(address & !3, now).ok()?;
        return Some(narrow(word, address, size));
    }
    let mut bytes = [0u8; 4];
    engine
        .mem_read(u64::from(address), &mut bytes[..size as usize])
        .ok()?;
    Some(u32::from_le_bytes(bytes))
}

fn write_any(
    engine: &mut Unicorn<'_, State>,
    address: u32,
    size: u32,
    value: u32,
    now: Cycles,
) -> Option<()> {
    if is_register(address) {
        let board = &mut engine.get_data_mut().board;
        let word = widen(board, address, size, value, now)?;
        board.write(address & !3, word, now).ok()?;
        return Some(());
    }
    engine
        .mem_write(u64::from(address), &value.to_le_bytes()[..size as usize])
        .ok()
}

/// The `size` bytes at `address` out of the word that holds them.
fn narrow(word: u32, address: u32, size: u32) -> u32 {
    let shifted = word >> (8 * (address & 3));
    match size {
        1 => shifted & 0xFF,
        2 => shifted & 0xFFFF,
        _ => shifted,
    }
}

/// A write of `size` bytes at `address` as a word: the other bytes as the register reads.
fn widen(board: &mut Board, address: u32, size: u32, value: u32, now: Cycles) -> Option<u32> {
    if size >= 4 {
        return Some(value);
    }
    let shift = 8 * (address & 3);
    let mask = if size == 1 { 0xFF } else { 0xFFFF } << shift;
    let current = board.read(address & !3, now).unwrap_or(0);
    Some((current & !mask) | ((value << shift) & mask))
}

/// The engine's hooks: every instruction (time, hints, the slice's budget), the peripherals'
/// bus, CPU exceptions.
fn install_hooks(engine: &mut Unicorn<'_, State>) -> Result<(), TwinError> {
    let hook = engine_error("install its hooks");
    engine
        .add_code_hook(0, u64::MAX, |uc, address, size| {
            let state = uc.get_data_mut();
            let address = address as u32;
            if state.executed >= state.budget {
                state.end = Some(SliceEnd::Budget);
                let _ = uc.emu_stop();
                return;
            }
            // A register write that asks for the machine stops the core here, at the next
            // instruction, where its state is whole.
            if let Some(end) = state.requested.take() {
                state.end = Some(end);
                let _ = uc.emu_stop();
                return;
            }
            if size == 2 {
                if let Some(hint) = state.image.hint(address) {
                    state.end = Some(SliceEnd::Hint(hint, address));
                    let _ = uc.emu_stop();
                    return;
                }
            }
            state.pc = address;
            state.executed += 1;
            if let Some(work) = state.edge.as_mut() {
                work.instructions += 1;
                work.code_bytes += u64::from(size);
            }
        })
        .map_err(&hook)?;
    for (base, bytes) in [(PERIPHERALS, PERIPHERALS_BYTES), (PRIVATE, PRIVATE_BYTES)] {
        engine
            .mmio_map(
                base,
                bytes,
                Some(
                    move |uc: &mut Unicorn<'_, State>, offset: u64, size: usize| {
                        let address = (base + offset) as u32;
                        let state = uc.get_data_mut();
                        let now = state.now();
                        if address & !3 == 0x4000_0824 {
                            state.deliver_outputs();
                            let count = state.plate.count(now);
                            state.board.set_encoder(count as u32);
                        }
                        match state.board.read(address & !3, now) {
                            Ok(word) => u64::from(narrow(word, address, size as u32)),
                            Err(refused) => {
                                state.end = Some(SliceEnd::Refused {
                                    address: refused.address,
                                    pc: state.pc,
                                    write: false,
                                });
                                let _ = uc.emu_stop();
                                0
                            }
                        }
                    },
                ),
                Some(
                    move |uc: &mut Unicorn<'_, State>, offset: u64, size: usize, value: u64| {
                        let address = (base + offset) as u32;
                        let state = uc.get_data_mut();
                        let now = state.now();
                        if address == TIM2_ARR {
                            if let Some(work) = state.edge.take() {
                                if work.instructions > state.worst_edge.instructions {
                                    state.worst_edge = work;
                                }
                                state.edges_measured += 1;
                            }
                        }
                        let result =
                            widen(&mut state.board, address, size as u32, value as u32, now)
                                .ok_or(())
                                .and_then(|word| {
                                    state.board.write(address & !3, word, now).map_err(|_| ())
                                });
                        match result {
                            Err(()) => {
                                state.end = Some(SliceEnd::Refused {
                                    address: address & !3,
                                    pc: state.pc,
                                    write: true,
                                });
                                let _ = uc.emu_stop();
                            }
                            Ok(Request::Reset) => state.requested = Some(SliceEnd::SystemReset),
                            Ok(Request::Evaluate) => {
                                move_items(uc);
                                let state = uc.get_data_mut();
                                state.deliver_outputs();
                                if state.board.scs.highest_pending().is_some()
                                    && state.requested.is_none()
                                {
                                    state.requested = Some(SliceEnd::Evaluate);
                                }
                            }
                            Ok(Request::None) => {}
                        }
                    },
                ),
            )
            .map_err(&hook)?;
    }
    engine
        .add_mem_hook(
            HookType::MEM_READ,
            FLASH,
            FLASH + FLASH_BYTES - 1,
            |uc, _kind, _address, _size, _value| {
                if let Some(work) = uc.get_data_mut().edge.as_mut() {
                    work.flash_reads += 1;
                }
                true
            },
        )
        .map_err(&hook)?;
    engine
        .add_mem_hook(
            HookType::MEM_INVALID,
            0,
            u64::MAX,
            |uc, _kind, address, _size, _value| {
                uc.get_data_mut().bad_access = Some(address as u32);
                false
            },
        )
        .map_err(&hook)?;
    engine
        .add_intr_hook(|uc, number| {
            let state = uc.get_data_mut();
            state.end = Some(SliceEnd::CpuException(number));
            let _ = uc.emu_stop();
        })
        .map_err(&hook)?;
    Ok(())
}
