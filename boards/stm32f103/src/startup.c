/*
 * Vector table and reset entry for the STM32F103 (RM0008 10.1.2, Table 63:
 * 16 Cortex-M3 exceptions + 43 medium-density IRQs).
 */
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "stm32f103_regs.h"

extern uint32_t __stack_top;
extern uint32_t __data_start, __data_end, __data_load, __bss_start, __bss_end;
int main(void);

void Reset_Handler(void);
void Default_Handler(void);
void NMI_Handler(void) __attribute__((weak, alias("Default_Handler")));
void HardFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void MemManage_Handler(void) __attribute__((weak, alias("Default_Handler")));
void BusFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void UsageFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void SVC_Handler(void) __attribute__((weak, alias("Default_Handler")));
void DebugMon_Handler(void) __attribute__((weak, alias("Default_Handler")));
void PendSV_Handler(void) __attribute__((weak, alias("Default_Handler")));
void SysTick_Handler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USART1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));

typedef void (*vector_entry)(void);

__attribute__((section(".isr_vector"), used)) static const vector_entry vector_table[16u + IRQ_COUNT] = {
    [0] = (vector_entry)(uintptr_t)&__stack_top,
    [1] = Reset_Handler,
    [2] = NMI_Handler,
    [3] = HardFault_Handler,
    [4] = MemManage_Handler,
    [5] = BusFault_Handler,
    [6] = UsageFault_Handler,
    [11] = SVC_Handler,
    [12] = DebugMon_Handler,
    [14] = PendSV_Handler,
    [15] = SysTick_Handler,
    [16u + IRQ_DMA1_CHANNEL1] = DMA1_Channel1_IRQHandler,
    [16u + IRQ_USART1] = USART1_IRQHandler,
    /* Every other IRQ is never enabled; fill with the default handler anyway. */
    [16 ... 16 + IRQ_DMA1_CHANNEL1 - 1] = Default_Handler,
    [16 + IRQ_DMA1_CHANNEL1 + 1 ... 16 + IRQ_USART1 - 1] = Default_Handler,
    [16 + IRQ_USART1 + 1 ... 16 + IRQ_COUNT - 1] = Default_Handler,
};

void Reset_Handler(void)
{
    /* First: compressor and valves off, before anything can stall or fault. */
    board_outputs_safe_early();

    memcpy(&__data_start, &__data_load, (size_t)((uintptr_t)&__data_end - (uintptr_t)&__data_start));
    memset(&__bss_start, 0, (size_t)((uintptr_t)&__bss_end - (uintptr_t)&__bss_start));

    board_clock_init();
    (void)main();
    for (;;) {
    }
}

/* Unexpected exception or IRQ: outputs safe, then wait for the watchdog to
 * reset the chip (it keeps running from LSI whatever state the core is in). */
void Default_Handler(void)
{
    board_outputs_safe_early();
    for (;;) {
    }
}
