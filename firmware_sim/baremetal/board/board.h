/**
 * @file board.h
 * @brief Minimal board support for the MPS2 boards emulated by qemu-system-arm
 *        (mps2-an386: Cortex-M4F, mps2-an500: Cortex-M7). Output and exit status go
 *        through semihosting (newlib's librdimon: printf, exit).
 */
#ifndef MSID_BOARD_H
#define MSID_BOARD_H

#include <stdint.h>

/**
 * @brief Start the SysTick counter (processor clock, 25 MHz on MPS2) with a wrap
 *        interrupt that extends it to 64 bits. Under `qemu -icount shift=0` one
 *        instruction advances the virtual clock by 1 ns, so one tick is 40 instructions.
 */
void board_ticks_start(void);

/** @brief SysTick ticks since ::board_ticks_start (monotonic, 64-bit). */
uint64_t board_ticks(void);

/** @brief Processor clock of the SysTick counter in Hz (25 MHz on MPS2). */
#define BOARD_TICK_HZ 25000000u

#endif
