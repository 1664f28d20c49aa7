/* Startup for the MPS2 boards under qemu-system-arm: vector table, FPU on,
 * .data copied from flash, .bss zeroed, semihosting opened, main() run, its
 * return value the exit status (semihosting SYS_EXIT, seen by qemu). */
#include <stdint.h>
#include <stdlib.h>
#include "board.h"

extern uint32_t __data_load__, __data_start__, __data_end__, __bss_start__, __bss_end__, __stack_top__;
extern int main(void);
extern void initialise_monitor_handles(void);   /* librdimon */
extern void __libc_init_array(void);

/* -nostartfiles drops crti/crtn: the empty _init/_fini newlib's init/fini arrays call. */
void _init(void) {}
void _fini(void) {}

#define REG(a) (*(volatile uint32_t *)(a))
#define SCB_CPACR 0xE000ED88u
#define SYST_CSR 0xE000E010u
#define SYST_RVR 0xE000E014u
#define SYST_CVR 0xE000E018u

static volatile uint64_t tick_hi;   /* ticks of completed SysTick wraps */

void Reset_Handler(void)
{
    REG(SCB_CPACR) |= 0xFu << 20;   /* CP10, CP11 full access: FPU on */
    __asm volatile("dsb\n\tisb" ::: "memory");
    uint32_t *src = &__data_load__, *dst = &__data_start__;
    while (dst < &__data_end__) *dst++ = *src++;
    for (dst = &__bss_start__; dst < &__bss_end__;) *dst++ = 0u;
    initialise_monitor_handles();
    __libc_init_array();
    exit(main());
}

static void Fault_Handler(void)
{
    /* a fault in a test is a failure: exit status 99 through semihosting */
    exit(99);
}

static void SysTick_Handler(void) { tick_hi += 1u << 24; }

void board_ticks_start(void)
{
    REG(SYST_CSR) = 0u;
    tick_hi = 0u;
    REG(SYST_RVR) = 0xFFFFFFu;
    REG(SYST_CVR) = 0u;
    REG(SYST_CSR) = 7u;   /* processor clock, interrupt on wrap, enable */
    while (REG(SYST_CVR) == 0u) {}   /* the first tick loads the reload value */
}

uint64_t board_ticks(void)
{
    uint64_t hi;
    uint32_t v;
    do {   /* re-read if a wrap was taken in between */
        hi = tick_hi;
        v = REG(SYST_CVR);
    } while (hi != tick_hi);
    return hi + (0xFFFFFFu - v);
}

typedef void (*vector)(void);
__attribute__((section(".vectors"), used)) static const vector vectors[16] = {
    (vector)(uintptr_t)&__stack_top__, Reset_Handler,
    Fault_Handler, Fault_Handler, Fault_Handler, Fault_Handler, Fault_Handler, /* NMI, Hard, Mem, Bus, Usage */
    0, 0, 0, 0, Fault_Handler /* SVC */, Fault_Handler /* DebugMon */, 0, Fault_Handler /* PendSV */,
    SysTick_Handler};
