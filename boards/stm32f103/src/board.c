/*
 * Clocks, DWT cycle counter and the independent watchdog (the 1 ms time
 * base, SysTick, is the HAL's: hal_stm32f103.c).
 */
#include "board.h"

#include "stm32f103_regs.h"

static board_clocks s_clocks;
static volatile bool s_clock_fault_event;
static bool s_reset_by_watchdog;

/* Called from Reset_Handler before .data/.bss exist: registers only.
 * GPIO clocks on, output latches low (PB12-15 off) / high (PC13 LED dark)
 * BEFORE the pins become outputs, so they never glitch on. Until this runs the
 * pins float as inputs and the driver's gate pull-downs keep the loads off. */
void board_outputs_safe_early(void)
{
    RCC->APB2ENR |= RCC_APB2ENR_IOPAEN | RCC_APB2ENR_IOPBEN | RCC_APB2ENR_IOPCEN;
    GPIOB->BRR = 0xFu << BOARD_OUT_PORT_PINS_FIRST;
    GPIOC->BSRR = 1u << BOARD_LED_PIN;
    GPIOA->BRR = 1u << BOARD_DE_PIN; /* RS-485 driver off: never hog the bus */

    uint32_t crh = GPIOB->CRH;
    for (uint32_t pin = BOARD_OUT_PORT_PINS_FIRST; pin < BOARD_OUT_PORT_PINS_FIRST + 4u; pin++) {
        uint32_t shift = (pin - 8u) * 4u;
        crh = (crh & ~(0xFu << shift)) | (GPIO_CFG_OUT_PP_2MHZ << shift);
    }
    GPIOB->CRH = crh;
    GPIOC->CRH = (GPIOC->CRH & ~(0xFu << ((BOARD_LED_PIN - 8u) * 4u))) |
                 (GPIO_CFG_OUT_PP_2MHZ << ((BOARD_LED_PIN - 8u) * 4u));
    GPIOA->CRH = (GPIOA->CRH & ~(0xFu << ((BOARD_DE_PIN - 8u) * 4u))) |
                 (GPIO_CFG_OUT_PP_2MHZ << ((BOARD_DE_PIN - 8u) * 4u));
}

/* Busy-wait for a flag with a bounded loop. At 8 MHz HSI each iteration is at
 * least 4 cycles (load, test, decrement, branch), so 100000 iterations is
 * >= 50 ms: ample for the 8 MHz crystal (2 ms typical start-up, DS5319) and for
 * PLL lock (200 us max). */
#define CLOCK_WAIT_ITERATIONS 100000u
static bool wait_set(volatile uint32_t *reg, uint32_t mask, uint32_t value)
{
    for (uint32_t i = 0; i < CLOCK_WAIT_ITERATIONS; i++) {
        if ((*reg & mask) == value) {
            return true;
        }
    }
    return false;
}

static bool pll_start_and_switch(uint32_t cfgr)
{
    RCC->CFGR = cfgr; /* SW = HSI while the PLL is configured */
    RCC->CR |= RCC_CR_PLLON;
    if (!wait_set(&RCC->CR, RCC_CR_PLLRDY, RCC_CR_PLLRDY)) {
        RCC->CR &= ~RCC_CR_PLLON;
        return false;
    }
    RCC->CFGR = cfgr | (RCC_CFGR_SW_PLL << RCC_CFGR_SW_POS);
    return wait_set(&RCC->CFGR, 3u << RCC_CFGR_SWS_POS, RCC_CFGR_SW_PLL << RCC_CFGR_SWS_POS);
}

/* AHB /1, APB1 /2 (<= 36 MHz), APB2 /1, ADC /6 (<= 14 MHz). */
#define CLOCK_PRESCALERS (RCC_CFGR_PPRE1_DIV2 | RCC_CFGR_ADCPRE_DIV6)

/* HSI/2 x16 = 64 MHz (the F1 PLL's limit from HSI), or the bare 8 MHz HSI. */
static void clock_use_hsi(void)
{
    /* Off HSE and the PLL first: PLLSRC/PLLMUL only change while the PLL is off. */
    RCC->CFGR = CLOCK_PRESCALERS; /* SW = HSI */
    (void)wait_set(&RCC->CFGR, 3u << RCC_CFGR_SWS_POS, 0u);
    RCC->CR &= ~(RCC_CR_PLLON | RCC_CR_HSEON | RCC_CR_CSSON);
    (void)wait_set(&RCC->CR, RCC_CR_PLLRDY, 0u);
    if (pll_start_and_switch(CLOCK_PRESCALERS | ((16u - 2u) << RCC_CFGR_PLLMUL_POS))) {
        s_clocks = (board_clocks){.sysclk_hz = 64000000u, .pclk1_hz = 32000000u, .pclk2_hz = 64000000u,
                                  .hse_failed = true};
        return;
    }
    /* Last resort: the 8 MHz HSI itself (ADC 8/6 = 1.33 MHz, still correct). */
    RCC->CFGR = CLOCK_PRESCALERS;
    s_clocks = (board_clocks){.sysclk_hz = BOARD_HSI_HZ, .pclk1_hz = BOARD_HSI_HZ / 2u,
                              .pclk2_hz = BOARD_HSI_HZ, .hse_failed = true};
}

void board_clock_init(void)
{
    s_reset_by_watchdog = (RCC->CSR & RCC_CSR_IWDGRSTF) != 0u;
    RCC->CSR |= RCC_CSR_RMVF;

    /* 2 wait states + prefetch: required above 48 MHz, harmless below. */
    FLASH_IF->ACR = FLASH_ACR_PRFTBE | FLASH_ACR_LATENCY_2;

    RCC->CR |= RCC_CR_HSEON;
    if (wait_set(&RCC->CR, RCC_CR_HSERDY, RCC_CR_HSERDY) &&
        pll_start_and_switch(CLOCK_PRESCALERS | RCC_CFGR_PLLSRC_HSE | ((9u - 2u) << RCC_CFGR_PLLMUL_POS))) {
        s_clocks = (board_clocks){.sysclk_hz = 72000000u, .pclk1_hz = 36000000u, .pclk2_hz = 72000000u,
                                  .hse_failed = false};
        /* Clock security: if the crystal stops later the hardware switches to
         * HSI and raises the NMI (RM0008 7.2.7). */
        RCC->CR |= RCC_CR_CSSON;
        return;
    }
    clock_use_hsi();
}

/* CSS: HSE failed at run time. The hardware already runs us on the 8 MHz HSI
 * with HSE and PLL off; bring the PLL back up from HSI. The NMI handler (with
 * the time base, in hal_stm32f103.c) then re-times SysTick and the USART. */
bool board_clock_recover_after_css(void)
{
    if (!(RCC->CIR & RCC_CIR_CSSF))
        return false;
    RCC->CIR = RCC_CIR_CSSC;
    clock_use_hsi();
    s_clock_fault_event = true;
    return true;
}

bool board_take_clock_fault_event(void)
{
    bool event = s_clock_fault_event;
    s_clock_fault_event = false;
    return event;
}

const board_clocks *board_clock(void) { return &s_clocks; }

bool board_reset_was_watchdog(void) { return s_reset_by_watchdog; }

/* ---- DWT cycle counter: cost of one control tick ---- */
void board_cycle_counter_init(void)
{
    COREDEBUG_DEMCR |= COREDEBUG_DEMCR_TRCENA;
    DWT_CYCCNT = 0;
    DWT_CTRL |= DWT_CTRL_CYCCNTENA;
}

uint32_t board_cycles(void) { return DWT_CYCCNT; }

/* ---- Independent watchdog ----
 * LSI 40 kHz nominal (30..60 kHz over temperature/parts, DS5319), /32 ->
 * 1.25 kHz; reload 375 -> 300 ms nominal, 200..400 ms worst case. The main loop
 * refreshes it every 10 ms tick; a page erase stalls at most ~40 ms. */
#define IWDG_RELOAD 375u

void board_watchdog_start(void)
{
    DBGMCU_CR |= DBGMCU_CR_IWDG_STOP; /* do not reset under a halted debugger */
    IWDG->KR = IWDG_KEY_START;
    IWDG->KR = IWDG_KEY_ACCESS;
    IWDG->PR = IWDG_PR_DIV32;
    IWDG->RLR = IWDG_RELOAD;
    for (uint32_t i = 0; i < CLOCK_WAIT_ITERATIONS && IWDG->SR != 0u; i++) {
        /* PVU/RVU clear once the LSI domain took the new values */
    }
    IWDG->KR = IWDG_KEY_REFRESH;
}

void board_watchdog_refresh(void) { IWDG->KR = IWDG_KEY_REFRESH; }
