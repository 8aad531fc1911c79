//! The NUCLEO-G474RE's own release image on the twin (`FEEDER_G474_ELF`, built with
//! `hil-trace` by `cargo xtask test`): the register values the review of the board's code
//! checked, as the image leaves them after its start-up, and a run with the user button whose
//! every segment reaches the DAC's output on its tick.

use std::path::PathBuf;

use feeder_shared::plan::EDGE_WORK_INSTRUCTIONS;
use feeder_twin::log::LogTable;
use feeder_twin::outputs::{Levels, OutputRecord};
use feeder_twin::scenario::button_run;
use feeder_twin::{Machine, CORE_HZ};

fn image() -> PathBuf {
    std::env::var_os("FEEDER_G474_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_ELF names the G474 image (cargo xtask test sets it)")
}

#[test]
#[ignore = "needs the G474 image; run by cargo xtask test"]
fn start_up_leaves_the_reviewed_register_values() {
    let mut machine = Machine::load(&image(), Box::new(OutputRecord::default())).expect("loads");
    machine
        .run_until(CORE_HZ / 100)
        .expect("runs 10 ms from reset");
    let expected = [
        // TIM2 CR2: MMS = 010, TRGO on the update event.
        (0x4000_0004, 0x20, "TIM2 CR2"),
        // TIM3 SMCR: TS = 001 (ITR1 = TIM2's TRGO), SMS = 111 (external clock mode 1).
        (0x4000_0408, 0x17, "TIM3 SMCR"),
        // DAC1 CR: EN1, TEN1, TSEL1 = 4 (TIM2's TRGO).
        (0x5000_0800, 0x13, "DAC1 CR"),
        // DAC1 DOR1: the zero code.
        (0x5000_082C, 2048, "DAC1 DOR1"),
        // DBGMCU APB1FZR1: TIM2 and TIM3 stop on a halt, the IWDG runs on (bit 12 clear).
        (0xE004_2008, 0x3, "DBGMCU APB1FZR1"),
        // DBGMCU APB2FZR: TIM1 stops on a halt.
        (0xE004_2010, 0x800, "DBGMCU APB2FZR"),
    ];
    for (address, value, name) in &expected {
        assert_eq!(
            machine.register(*address),
            Some(*value),
            "{name} at 0x{address:08x}"
        );
    }
    // FLASH ACR: four wait states at 170 MHz (RM0440, "Read access latency").
    let acr = machine.register(0x4002_2000).expect("FLASH ACR");
    assert_eq!(acr & 0xF, 4, "FLASH ACR latency: {acr:#x}");
    // GPIOA: PA10, the driver enable, an output driven low; PA4 in analog mode.
    let moder = machine.register(0x4800_0000).expect("GPIOA MODER");
    assert_eq!((moder >> 20) & 3, 1, "PA10 an output: {moder:#x}");
    assert_eq!((moder >> 8) & 3, 3, "PA4 analog: {moder:#x}");
    assert_eq!(
        machine.register(0x4800_0014).map(|odr| odr & (1 << 10)),
        Some(0)
    );
    assert_priorities(&machine, 28);
}

/// The segment timer's update (IRQ `edge_irq`) alone at priority 0, above every other enabled
/// interrupt; the control executor (UART4, IRQ 52) at 1.
fn assert_priorities(machine: &Machine, edge_irq: u32) {
    let priority = |irq: u32| {
        machine
            .register(0xE000_E400 + (irq & !3))
            .map(|word| (word >> (8 * (irq & 3))) & 0xFF)
    };
    let enabled = |irq: u32| {
        machine
            .register(0xE000_E100 + 4 * (irq / 32))
            .is_some_and(|word| word & (1 << (irq % 32)) != 0)
    };
    assert!(enabled(edge_irq), "the edge's interrupt is enabled");
    assert_eq!(priority(edge_irq), Some(0x00), "the edge's priority");
    assert_eq!(priority(52), Some(0x10), "UART4's priority");
    let beside: Vec<(u32, Option<u32>)> = (0..102)
        .filter(|&irq| irq != edge_irq && enabled(irq))
        .map(|irq| (irq, priority(irq)))
        .filter(|(_, p)| !p.is_some_and(|p| p >= 0x10))
        .collect();
    assert!(
        beside.is_empty(),
        "enabled at the edge's priority (IRQ, priority): {beside:?}"
    );
}

/// The encoder image (`FEEDER_G474_ENCODER_ELF`): the sampling's DMA routed from TIM6's and
/// TIM2's update requests (RM0440's DMAMUX request IDs 8 and 60), TIM4 in encoder mode 3 with
/// its input filter, TIM6 overflowing every 250 µs, DMA1 channel 1 circular into the samples.
#[test]
#[ignore = "needs the G474 encoder image; run by cargo xtask test"]
fn the_encoder_image_routes_its_sampling_as_reviewed() {
    let elf = std::env::var_os("FEEDER_G474_ENCODER_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_ENCODER_ELF names the encoder image");
    let mut machine = Machine::load(&elf, Box::new(OutputRecord::default())).expect("loads");
    machine
        .run_until(CORE_HZ / 100)
        .expect("runs 10 ms from reset");
    let expected = [
        (0x4002_0800, 8, "DMAMUX1 C0CR: TIM6_UP"),
        (0x4002_0804, 60, "DMAMUX1 C1CR: TIM2_UP"),
        (0x4000_102C, 42_499, "TIM6 ARR: 250 µs at 170 MHz"),
        (
            0x4002_0008,
            0x35A1,
            "DMA1 CCR1: circular, 16-bit, memory increment, very high",
        ),
        (0x4002_0010, 0x4000_0824, "DMA1 CPAR1: TIM4's count"),
        (
            0xE004_2008,
            0x13,
            "DBGMCU APB1FZR1: TIM2, TIM3 and TIM6 stop on a halt",
        ),
    ];
    for (address, value, name) in &expected {
        assert_eq!(machine.register(*address), Some(*value), "{name}");
    }
    // The sampling's buffers, which DMA writes, in SRAM1 or SRAM2 (below the CCM SRAM's alias
    // at 0x2001_8000): where the DMA reaches them through the bus matrix.
    for part in ["encoder7SAMPLES", "encoder8CAPTURES"] {
        let found = machine.symbols_containing(part);
        assert_eq!(found.len(), 1, "{part}: {found:?}");
        let (name, address) = &found[0];
        assert!(
            (0x2000_0000..0x2001_8000).contains(address),
            "{name} at {address:#x}"
        );
    }
    let smcr = machine.register(0x4000_0808).expect("TIM4 SMCR");
    assert_eq!(smcr & 0x7, 3, "TIM4 in encoder mode 3: {smcr:#x}");
    let ccmr1 = machine.register(0x4000_0818).expect("TIM4 CCMR1");
    assert_eq!(
        ccmr1 & 0xF3F3,
        0x3131,
        "TI1 and TI2, filtered over 8 clocks: {ccmr1:#x}"
    );
    assert_priorities(&machine, 28);
    // The closed loop's course (the loop executor on CORDIC's vector, IRQ 100) one level above
    // the other tasks (the task executor on UART5's, IRQ 53), the console's commands among them.
    for (irq, expected, name) in [
        (100, 0xE0, "CORDIC: the loop executor"),
        (53, 0xF0, "UART5: the task executor"),
    ] {
        let word = machine
            .register(0xE000_E400 + (irq & !3))
            .expect("NVIC IPR");
        assert_eq!(
            (word >> (8 * (irq & 3))) & 0xFF,
            expected,
            "{name}'s priority"
        );
        let enabled = machine
            .register(0xE000_E100 + 4 * (irq / 32))
            .expect("NVIC ISER");
        assert_ne!(enabled & (1 << (irq % 32)), 0, "{name} enabled");
    }
}

#[test]
#[ignore = "needs the G474 image; run by cargo xtask test"]
fn a_button_run_latches_every_segment_on_its_tick() {
    let elf = image();
    let bytes = std::fs::read(&elf).expect("the image");
    let table = LogTable::load(&bytes).expect("its defmt table");
    let record = OutputRecord::default();
    let mut machine = Machine::load(&elf, Box::new(record.clone())).expect("loads");
    let mut log = Vec::new();
    let outcome = button_run(
        &mut machine,
        table.decoder(),
        &mut log,
        20,
        &record,
        Levels::Planned,
    )
    .expect("runs");
    let text = String::from_utf8(log).expect("text");
    assert!(outcome.completed, "{text}");
    assert!(
        outcome.outputs.problems.is_empty(),
        "{:?}",
        outcome.outputs.problems
    );
    assert_eq!(outcome.outputs.stray, 0);
    // Idle periods before the start and after the stop, the ramps' and the 20 cycles' four
    // segments each.
    assert!(
        outcome.outputs.matched > 4 * 20,
        "{}",
        outcome.outputs.matched
    );
    assert!(
        text.contains("Stopped -> Running") && text.ends_with("\n"),
        "{text}"
    );
    assert!(text
        .lines()
        .last()
        .is_some_and(|line| line.starts_with("EVT end tick=")));
    // The worst edge's work, from the edge to the next preload, within what the segment floor
    // gives an edge: `EDGE_WORK_INSTRUCTIONS`, and at the firmware's 1.5 cycles an instruction
    // (`board/g474/segment_timer.rs`) its cycles even with no hit in the ART accelerator.
    let (work, edges) = machine.edge_work();
    assert!(edges > 4 * 20, "{edges} edges measured");
    let wait_states = u64::from(machine.board().flash_wait_states());
    let cycles = work.cycles_without_cache(wait_states);
    assert!(
        work.instructions as f64 <= EDGE_WORK_INSTRUCTIONS
            && cycles as f64 <= 1.5 * EDGE_WORK_INSTRUCTIONS,
        "{work:?}: at most {cycles} cycles"
    );
}
