//! The Cortex-M4's system control space (ARMv7-M ARM, B3): the NVIC's enable, pending, active
//! and priority registers and the software trigger; the SCB (CPUID, ICSR's PendSV, VTOR,
//! AIRCR's priority grouping and reset request, SCR, CCR, the system handlers' priorities and
//! states, the fault status registers, CPACR); the FPU's context control; the DWT's cycle
//! counter; SysTick as storage (the firmware's time runs on a timer).
//!
//! Which exception the core takes, and when, follows from the state kept here
//! ([`Scs::highest_pending`]); entering and leaving one is the machine's.

use super::Access;

/// Interrupt lines of the STM32G474 (RM0440, "Interrupt and exception vectors").
pub const IRQS: usize = 102;
/// Priority bits the STM32G4 implements (the upper four of each byte).
const PRIORITY_MASK: u8 = 0xF0;

/// Exception numbers.
pub const NMI: u32 = 2;
pub const HARD_FAULT: u32 = 3;
pub const PEND_SV: u32 = 14;
pub const SYS_TICK: u32 = 15;
/// The first external interrupt's exception number.
pub const IRQ_BASE: u32 = 16;

/// CPUID of a Cortex-M4 r0p1.
const CPUID: u32 = 0x410F_C241;
const AIRCR_VECTKEY: u32 = 0x05FA;
const AIRCR_SYSRESETREQ: u32 = 1 << 2;
const ICSR_PENDSVSET: u32 = 1 << 28;
const ICSR_PENDSVCLR: u32 = 1 << 27;
const ICSR_NMIPENDSET: u32 = 1 << 31;
const ICSR_PENDSTSET: u32 = 1 << 26;
const ICSR_PENDSTCLR: u32 = 1 << 25;
/// SCR's SEVONPEND: a newly pending interrupt wakes a WFE.
pub const SCR_SEVONPEND: u32 = 1 << 4;

/// What a write to the system control space asks of the machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    None,
    /// AIRCR.SYSRESETREQ: a system reset.
    Reset,
    /// Something became pending: look for an exception to take.
    Evaluate,
}

#[derive(Debug, Clone)]
pub struct Scs {
    enabled: [bool; IRQS],
    pending: [bool; IRQS],
    /// Active exceptions, by exception number.
    active: [bool; IRQ_BASE as usize + IRQS],
    irq_priority: [u8; IRQS],
    /// SHPR1–3: priorities of exceptions 4–15.
    system_priority: [u8; 12],
    nmi_pending: bool,
    pend_sv: bool,
    sys_tick_pending: bool,
    vtor: u32,
    prigroup: u32,
    scr: u32,
    ccr: u32,
    shcsr: u32,
    cfsr: u32,
    hfsr: u32,
    mmfar: u32,
    bfar: u32,
    cpacr: u32,
    demcr: u32,
    fpccr: u32,
    fpcar: u32,
    fpdscr: u32,
    actlr: u32,
    systick: [u32; 3],
    dwt_ctrl: u32,
    /// The cycle count the DWT's CYCCNT read `dwt_base_count` at `dwt_base_at`.
    dwt_base_count: u32,
    dwt_base_at: u64,
    dwt_lar_unlocked: bool,
}

impl Default for Scs {
    fn default() -> Self {
        Self::new()
    }
}

impl Scs {
    pub fn new() -> Self {
        Scs {
            enabled: [false; IRQS],
            pending: [false; IRQS],
            active: [false; IRQ_BASE as usize + IRQS],
            irq_priority: [0; IRQS],
            system_priority: [0; 12],
            nmi_pending: false,
            pend_sv: false,
            sys_tick_pending: false,
            vtor: 0,
            prigroup: 0,
            scr: 0,
            ccr: 0x200,
            shcsr: 0,
            cfsr: 0,
            hfsr: 0,
            mmfar: 0,
            bfar: 0,
            cpacr: 0,
            demcr: 0,
            fpccr: 0xC000_0000,
            fpcar: 0,
            fpdscr: 0,
            actlr: 0,
            systick: [0; 3],
            dwt_ctrl: 0x4000_0000,
            dwt_base_count: 0,
            dwt_base_at: 0,
            dwt_lar_unlocked: false,
        }
    }

    /// Raises interrupt line `irq` (a level or a pulse: pending until taken or cleared).
    pub fn pend(&mut self, irq: usize) {
        self.pending[irq] = true;
    }

    pub fn pend_nmi(&mut self) {
        self.nmi_pending = true;
    }

    pub fn is_pending(&self, irq: usize) -> bool {
        self.pending[irq]
    }

    pub fn vector_table(&self) -> u32 {
        self.vtor
    }

    pub fn scr(&self) -> u32 {
        self.scr
    }

    /// The FPU's access (CPACR, CP10 and CP11 full).
    pub fn fpu_enabled(&self) -> bool {
        self.cpacr & 0x00F0_0000 == 0x00F0_0000
    }

    /// FPCCR's ASPEN: the core marks floating-point context and stacks it on exception entry.
    pub fn fp_stacking(&self) -> bool {
        self.fpccr & (1 << 31) != 0
    }

    /// The priority of exception `number` (negative for the fixed ones).
    pub fn priority(&self, number: u32) -> i32 {
        match number {
            1 => -3,
            NMI => -2,
            HARD_FAULT => -1,
            4..=15 => i32::from(self.system_priority[number as usize - 4]),
            _ => i32::from(self.irq_priority[(number - IRQ_BASE) as usize]),
        }
    }

    /// The group priority of `priority`: the bits above PRIGROUP + 1.
    pub fn group(&self, priority: i32) -> i32 {
        if priority < 0 {
            return priority;
        }
        let subgroup_bits = self.prigroup + 1;
        (priority >> subgroup_bits) << subgroup_bits
    }

    /// The running priority from the active exceptions (256 when none is active).
    pub fn active_priority(&self) -> i32 {
        (1..self.active.len() as u32)
            .filter(|&number| self.active[number as usize])
            .map(|number| self.group(self.priority(number)))
            .min()
            .unwrap_or(256)
    }

    /// The pending exception of the highest priority (the lowest number at a tie), with its
    /// priority.
    pub fn highest_pending(&self) -> Option<(u32, i32)> {
        let mut best: Option<(u32, i32)> = None;
        let mut consider = |number: u32, priority: i32| {
            if best.is_none_or(|(_, b)| priority < b) {
                best = Some((number, priority));
            }
        };
        if self.nmi_pending {
            consider(NMI, -2);
        }
        if self.pend_sv {
            consider(PEND_SV, self.priority(PEND_SV));
        }
        if self.sys_tick_pending {
            consider(SYS_TICK, self.priority(SYS_TICK));
        }
        for irq in 0..IRQS {
            if self.pending[irq] && self.enabled[irq] && !self.active[irq + IRQ_BASE as usize] {
                consider(irq as u32 + IRQ_BASE, self.priority(irq as u32 + IRQ_BASE));
            }
        }
        best
    }

    /// Exception `number` is taken: active, no longer pending.
    pub fn activate(&mut self, number: u32) {
        match number {
            NMI => self.nmi_pending = false,
            PEND_SV => self.pend_sv = false,
            SYS_TICK => self.sys_tick_pending = false,
            n if n >= IRQ_BASE => self.pending[(n - IRQ_BASE) as usize] = false,
            _ => {}
        }
        self.active[number as usize] = true;
    }

    /// Exception `number` returns.
    pub fn deactivate(&mut self, number: u32) {
        self.active[number as usize] = false;
    }

    pub fn is_active(&self, number: u32) -> bool {
        self.active.get(number as usize).copied().unwrap_or(false)
    }

    /// A HardFault escalated or forced: HFSR.FORCED or VECTTBL, with a configurable fault's
    /// status in CFSR.
    pub fn record_fault(&mut self, cfsr: u32, address: Option<u32>) {
        self.cfsr |= cfsr;
        self.hfsr |= 1 << 30;
        if let Some(address) = address {
            self.bfar = address;
        }
    }

    /// Reads at `offset` from 0xE000_0000; `now` for the cycle counter.
    pub fn read(&self, offset: u32, now: u64) -> Access {
        let bits = |flags: &[bool], word: u32| {
            (0..32).fold(0u32, |value, bit| {
                let index = (word * 32 + bit) as usize;
                if flags.get(index).copied().unwrap_or(false) {
                    value | 1 << bit
                } else {
                    value
                }
            })
        };
        let value = match offset {
            0x1000 => self.dwt_ctrl,
            0x1004 => {
                if self.dwt_ctrl & 1 != 0 {
                    self.dwt_base_count
                        .wrapping_add((now - self.dwt_base_at) as u32)
                } else {
                    self.dwt_base_count
                }
            }
            0x1FB4 => u32::from(!self.dwt_lar_unlocked) << 1 | 1,
            0xE004 => (IRQS as u32).div_ceil(32) - 1,
            0xE008 => self.actlr,
            0xE010 => self.systick[0],
            0xE014 => self.systick[1],
            0xE018 => self.systick[2],
            0xE01C => 0x4000_0000,
            0xE100..=0xE11C => bits(&self.enabled, (offset - 0xE100) / 4),
            0xE180..=0xE19C => bits(&self.enabled, (offset - 0xE180) / 4),
            0xE200..=0xE21C => bits(&self.pending, (offset - 0xE200) / 4),
            0xE280..=0xE29C => bits(&self.pending, (offset - 0xE280) / 4),
            0xE300..=0xE31C => bits(&self.active[IRQ_BASE as usize..], (offset - 0xE300) / 4),
            0xE400..=0xE4EC => {
                let first = (offset - 0xE400) as usize;
                (0..4).fold(0, |value, byte| {
                    let priority = self.irq_priority.get(first + byte).copied().unwrap_or(0);
                    value | u32::from(priority) << (8 * byte)
                })
            }
            0xED00 => CPUID,
            0xED04 => {
                let active = (1..self.active.len())
                    .find(|&n| self.active[n])
                    .unwrap_or(0) as u32;
                let pending = self.highest_pending().map_or(0, |(n, _)| n);
                active
                    | pending << 12
                    | u32::from(self.pend_sv) << 28
                    | u32::from(self.sys_tick_pending) << 26
                    | u32::from(self.nmi_pending) << 31
            }
            0xED08 => self.vtor,
            0xED0C => 0xFA05_0000 | self.prigroup << 8,
            0xED10 => self.scr,
            0xED14 => self.ccr,
            0xED18..=0xED20 => {
                let first = (offset - 0xED18) as usize;
                (0..4).fold(0, |value, byte| {
                    value | u32::from(self.system_priority[first + byte]) << (8 * byte)
                })
            }
            0xED24 => self.shcsr,
            0xED28 => self.cfsr,
            0xED2C => self.hfsr,
            0xED30 => 0,
            0xED34 => self.mmfar,
            0xED38 => self.bfar,
            0xED3C => 0,
            0xED88 => self.cpacr,
            0xEDF0 => 0,
            0xEDFC => self.demcr,
            0xEF34 => self.fpccr,
            0xEF38 => self.fpcar,
            0xEF3C => self.fpdscr,
            _ => return Access::Unmodelled,
        };
        Access::Value(value)
    }

    /// Writes at `offset` from 0xE000_0000.
    pub fn write(&mut self, offset: u32, value: u32, now: u64) -> Option<Request> {
        let set = |flags: &mut [bool], word: u32, value: u32, to: bool| {
            for bit in 0..32 {
                if value & (1 << bit) != 0 {
                    if let Some(flag) = flags.get_mut((word * 32 + bit) as usize) {
                        *flag = to;
                    }
                }
            }
        };
        match offset {
            0x1000 => {
                let count = self.read(0x1004, now);
                if let Access::Value(count) = count {
                    self.dwt_base_count = count;
                }
                self.dwt_base_at = now;
                self.dwt_ctrl = (self.dwt_ctrl & 0xF000_0000) | (value & 0x0FFF_FFFF);
            }
            0x1004 => {
                self.dwt_base_count = value;
                self.dwt_base_at = now;
            }
            0x1FB0 => self.dwt_lar_unlocked = value == 0xC5AC_CE55,
            0xE008 => self.actlr = value,
            0xE010..=0xE018 => {
                let index = ((offset - 0xE010) / 4) as usize;
                if index == 0 && value & 1 != 0 {
                    return None;
                }
                self.systick[index] = value;
            }
            0xE100..=0xE11C => {
                set(&mut self.enabled, (offset - 0xE100) / 4, value, true);
                return Some(Request::Evaluate);
            }
            0xE180..=0xE19C => set(&mut self.enabled, (offset - 0xE180) / 4, value, false),
            0xE200..=0xE21C => {
                set(&mut self.pending, (offset - 0xE200) / 4, value, true);
                return Some(Request::Evaluate);
            }
            0xE280..=0xE29C => set(&mut self.pending, (offset - 0xE280) / 4, value, false),
            0xE400..=0xE4EC => {
                let first = (offset - 0xE400) as usize;
                for byte in 0..4 {
                    if let Some(priority) = self.irq_priority.get_mut(first + byte) {
                        *priority = (value >> (8 * byte)) as u8 & PRIORITY_MASK;
                    }
                }
            }
            0xEF00 => {
                if let Some(flag) = self.pending.get_mut((value & 0x1FF) as usize) {
                    *flag = true;
                }
                return Some(Request::Evaluate);
            }
            0xED04 => {
                if value & ICSR_PENDSVSET != 0 {
                    self.pend_sv = true;
                }
                if value & ICSR_PENDSVCLR != 0 {
                    self.pend_sv = false;
                }
                if value & ICSR_PENDSTSET != 0 {
                    self.sys_tick_pending = true;
                }
                if value & ICSR_PENDSTCLR != 0 {
                    self.sys_tick_pending = false;
                }
                if value & ICSR_NMIPENDSET != 0 {
                    self.nmi_pending = true;
                }
                return Some(Request::Evaluate);
            }
            0xED08 => self.vtor = value & 0xFFFF_FF80,
            0xED0C => {
                if value >> 16 != AIRCR_VECTKEY {
                    return Some(Request::None);
                }
                self.prigroup = (value >> 8) & 7;
                if value & AIRCR_SYSRESETREQ != 0 {
                    return Some(Request::Reset);
                }
            }
            0xED10 => self.scr = value & 0x16,
            0xED14 => self.ccr = value,
            0xED18..=0xED20 => {
                let first = (offset - 0xED18) as usize;
                for byte in 0..4 {
                    self.system_priority[first + byte] =
                        (value >> (8 * byte)) as u8 & PRIORITY_MASK;
                }
            }
            0xED24 => self.shcsr = value,
            0xED28 => self.cfsr &= !value,
            0xED2C => self.hfsr &= !value,
            0xED30 | 0xED3C => {}
            0xED34 => self.mmfar = value,
            0xED38 => self.bfar = value,
            0xED88 => self.cpacr = value & 0x00F0_0000,
            0xEDF0 => {}
            0xEDFC => self.demcr = value,
            0xEF34 => self.fpccr = value,
            0xEF38 => self.fpcar = value,
            0xEF3C => self.fpdscr = value,
            _ => return None,
        }
        Some(Request::None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_highest_priority_pending_enabled_interrupt_is_chosen() {
        let mut scs = Scs::new();
        // IRQ 28 (TIM2) at 0, IRQ 52 (UART4) at 1 << 4.
        scs.write(0xE400 + 28, 0x00, 0);
        scs.write(0xE400 + 52, 0x10, 0);
        scs.write(0xE100, 1 << 28, 0);
        scs.write(0xE104, 1 << 20, 0);
        scs.write(0xEF00, 52, 0);
        assert_eq!(scs.highest_pending(), Some((IRQ_BASE + 52, 0x10)));
        scs.pend(28);
        assert_eq!(scs.highest_pending(), Some((IRQ_BASE + 28, 0)));
        scs.activate(IRQ_BASE + 28);
        assert_eq!(scs.active_priority(), 0);
        assert_eq!(scs.highest_pending(), Some((IRQ_BASE + 52, 0x10)));
    }

    #[test]
    fn a_disabled_interrupt_stays_pending_without_being_taken() {
        let mut scs = Scs::new();
        scs.pend(11);
        assert_eq!(scs.highest_pending(), None);
        assert_eq!(scs.read(0xE200, 0), Access::Value(1 << 11));
    }

    #[test]
    fn the_reset_request_needs_the_key() {
        let mut scs = Scs::new();
        assert_eq!(scs.write(0xED0C, AIRCR_SYSRESETREQ, 0), Some(Request::None));
        assert_eq!(
            scs.write(0xED0C, AIRCR_VECTKEY << 16 | AIRCR_SYSRESETREQ, 0),
            Some(Request::Reset)
        );
    }
}
