/*
 * The few STM32F103 (medium density, e.g. F103C8) and Cortex-M3 registers this
 * board uses. Written from:
 *   RM0008 Rev 21 "STM32F101xx..F107xx reference manual":
 *     3.3 memory map (Table 3), 3.3.3 flash (Table 5, 1 KB pages), 7.3 RCC,
 *     9.2 GPIO/AFIO, 10.1.2 vector table (Table 63), 11.12 ADC, 13.4 DMA
 *     (Table 78: ADC1 on DMA1 channel 1), 19.4 IWDG, 27.6 USART;
 *   PM0075 (flash programming: keys, PG/PER/STRT, halfword programming);
 *   ARMv7-M ARM / Cortex-M3 TRM for SysTick, SCB, NVIC, DWT, CoreDebug.
 * Bit positions were cross-checked against the stm32-rs SVD field tables
 * (e.g. stm32-rs.github.io/stm32-rs/stm32f/stm32f1/RCC_0x40021000_CFGR_0x0004.html).
 * No vendor header is used or copied.
 */
#ifndef STM32F103_REGS_H
#define STM32F103_REGS_H

#include <stdint.h>

#define REG32(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

/* ---- RCC, 0x4002_1000 (RM0008 7.3) ---- */
typedef struct {
    volatile uint32_t CR, CFGR, CIR, APB2RSTR, APB1RSTR, AHBENR, APB2ENR, APB1ENR, BDCR, CSR;
} rcc_regs;
#define RCC ((rcc_regs *)0x40021000u)
#define RCC_CR_HSION (1u << 0)
#define RCC_CR_HSIRDY (1u << 1)
#define RCC_CR_HSEON (1u << 16)
#define RCC_CR_HSERDY (1u << 17)
#define RCC_CR_HSEBYP (1u << 18)
#define RCC_CR_CSSON (1u << 19)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_CFGR_SW_POS 0u        /* 00 HSI, 01 HSE, 10 PLL */
#define RCC_CFGR_SWS_POS 2u
#define RCC_CFGR_SW_PLL 2u
#define RCC_CFGR_PPRE1_DIV2 (4u << 8)  /* APB1 <= 36 MHz */
#define RCC_CFGR_ADCPRE_DIV6 (2u << 14) /* ADC clock <= 14 MHz */
#define RCC_CFGR_PLLSRC_HSE (1u << 16)  /* 0 = HSI/2 */
#define RCC_CFGR_PLLMUL_POS 18u         /* value n-2: x9 = 7, x16 = 14 */
#define RCC_CIR_CSSF (1u << 7)
#define RCC_CIR_CSSC (1u << 23)
#define RCC_APB2ENR_AFIOEN (1u << 0)
#define RCC_APB2ENR_IOPAEN (1u << 2)
#define RCC_APB2ENR_IOPBEN (1u << 3)
#define RCC_APB2ENR_IOPCEN (1u << 4)
#define RCC_APB2ENR_ADC1EN (1u << 9)
#define RCC_APB2ENR_USART1EN (1u << 14)
#define RCC_AHBENR_DMA1EN (1u << 0)
#define RCC_CSR_RMVF (1u << 24)
#define RCC_CSR_IWDGRSTF (1u << 29)

/* ---- FLASH interface, 0x4002_2000 (RM0008 3.3.3, PM0075 3) ---- */
typedef struct {
    volatile uint32_t ACR, KEYR, OPTKEYR, SR, CR, AR, RESERVED, OBR, WRPR;
} flash_regs;
#define FLASH_IF ((flash_regs *)0x40022000u)
#define FLASH_ACR_LATENCY_2 2u  /* 48 < SYSCLK <= 72 MHz */
#define FLASH_ACR_PRFTBE (1u << 4)
#define FLASH_KEY1 0x45670123u
#define FLASH_KEY2 0xCDEF89ABu
#define FLASH_SR_BSY (1u << 0)
#define FLASH_SR_PGERR (1u << 2)
#define FLASH_SR_WRPRTERR (1u << 4)
#define FLASH_SR_EOP (1u << 5)
#define FLASH_CR_PG (1u << 0)
#define FLASH_CR_PER (1u << 1)
#define FLASH_CR_STRT (1u << 6)
#define FLASH_CR_LOCK (1u << 7)
#define FLASH_BASE_ADDR 0x08000000u
#define FLASH_PAGE_BYTES 1024u   /* medium density */

/* ---- GPIO ports (RM0008 9.2), AFIO ---- */
typedef struct {
    volatile uint32_t CRL, CRH, IDR, ODR, BSRR, BRR, LCKR;
} gpio_regs;
#define GPIOA ((gpio_regs *)0x40010800u)
#define GPIOB ((gpio_regs *)0x40010C00u)
#define GPIOC ((gpio_regs *)0x40011000u)
/* 4-bit CNF[1:0]:MODE[1:0] per pin in CRL (pins 0-7) / CRH (pins 8-15). */
#define GPIO_CFG_ANALOG 0x0u
#define GPIO_CFG_INPUT_PULL 0x8u     /* pull-up when ODR bit = 1 */
#define GPIO_CFG_OUT_PP_2MHZ 0x2u
#define GPIO_CFG_AF_PP_50MHZ 0xBu

/* ---- ADC1, 0x4001_2400 (RM0008 11.12) ---- */
typedef struct {
    volatile uint32_t SR, CR1, CR2, SMPR1, SMPR2, JOFR1, JOFR2, JOFR3, JOFR4, HTR, LTR,
        SQR1, SQR2, SQR3, JSQR, JDR1, JDR2, JDR3, JDR4, DR;
} adc_regs;
#define ADC1 ((adc_regs *)0x40012400u)
#define ADC_CR1_SCAN (1u << 8)
#define ADC_CR2_ADON (1u << 0)
#define ADC_CR2_CONT (1u << 1)
#define ADC_CR2_CAL (1u << 2)
#define ADC_CR2_RSTCAL (1u << 3)
#define ADC_CR2_DMA (1u << 8)
#define ADC_CR2_EXTSEL_SWSTART (7u << 17)
#define ADC_CR2_EXTTRIG (1u << 20)
#define ADC_CR2_SWSTART (1u << 22)
#define ADC_SMP_239_5 7u              /* 3-bit field per channel */
#define ADC_SQR1_L_POS 20u            /* sequence length - 1 */

/* ---- DMA1, 0x4002_0000 (RM0008 13.4) ---- */
typedef struct {
    volatile uint32_t CCR, CNDTR, CPAR, CMAR, RESERVED;
} dma_channel_regs;
typedef struct {
    volatile uint32_t ISR, IFCR;
    dma_channel_regs CH[7]; /* CH[0] = channel 1 */
} dma_regs;
#define DMA1 ((dma_regs *)0x40020000u)
#define DMA_ISR_TCIF1 (1u << 1)
#define DMA_ISR_TEIF1 (1u << 3)
#define DMA_IFCR_CGIF1 (1u << 0)
#define DMA_CCR_EN (1u << 0)
#define DMA_CCR_TCIE (1u << 1)
#define DMA_CCR_TEIE (1u << 3)
#define DMA_CCR_CIRC (1u << 5)
#define DMA_CCR_MINC (1u << 7)
#define DMA_CCR_PSIZE_16 (1u << 8)
#define DMA_CCR_MSIZE_16 (1u << 10)
#define DMA_CCR_PL_HIGH (2u << 12)

/* ---- USART1, 0x4001_3800 on APB2 (RM0008 27.6) ---- */
typedef struct {
    volatile uint32_t SR, DR, BRR, CR1, CR2, CR3, GTPR;
} usart_regs;
#define USART1 ((usart_regs *)0x40013800u)
#define USART_SR_PE (1u << 0)
#define USART_SR_FE (1u << 1)
#define USART_SR_NE (1u << 2)
#define USART_SR_ORE (1u << 3)
#define USART_SR_RXNE (1u << 5)
#define USART_SR_TC (1u << 6)
#define USART_SR_TXE (1u << 7)
#define USART_CR1_RE (1u << 2)
#define USART_CR1_TE (1u << 3)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_TCIE (1u << 6)
#define USART_CR1_TXEIE (1u << 7)
#define USART_CR1_PS_ODD (1u << 9)
#define USART_CR1_PCE (1u << 10)
#define USART_CR1_M_9BIT (1u << 12) /* 8 data bits + parity */
#define USART_CR1_UE (1u << 13)

/* ---- IWDG, 0x4000_3000 (RM0008 19.4); LSI 30..60 kHz (datasheet) ---- */
typedef struct {
    volatile uint32_t KR, PR, RLR, SR;
} iwdg_regs;
#define IWDG ((iwdg_regs *)0x40003000u)
#define IWDG_KEY_ACCESS 0x5555u
#define IWDG_KEY_REFRESH 0xAAAAu
#define IWDG_KEY_START 0xCCCCu
#define IWDG_PR_DIV32 3u
/* DBGMCU_CR (RM0008 31.16.3): stop the IWDG while the core is halted. */
#define DBGMCU_CR REG32(0xE0042004u)
#define DBGMCU_CR_IWDG_STOP (1u << 8)

/* ---- Cortex-M3 core (ARMv7-M ARM B3) ---- */
typedef struct {
    volatile uint32_t CTRL, LOAD, VAL, CALIB;
} systick_regs;
#define SYSTICK ((systick_regs *)0xE000E010u)
#define SYSTICK_CTRL_ENABLE (1u << 0)
#define SYSTICK_CTRL_TICKINT (1u << 1)
#define SYSTICK_CTRL_CLKSOURCE_CPU (1u << 2)
#define NVIC_ISER(n) REG32(0xE000E100u + 4u * (n))
#define SCB_AIRCR REG32(0xE000ED0Cu)
#define SCB_AIRCR_SYSRESET (0x05FA0000u | (1u << 2))
#define DWT_CTRL REG32(0xE0001000u)
#define DWT_CYCCNT REG32(0xE0001004u)
#define DWT_CTRL_CYCCNTENA (1u << 0)
#define COREDEBUG_DEMCR REG32(0xE000EDFCu)
#define COREDEBUG_DEMCR_TRCENA (1u << 24)

/* IRQ numbers (RM0008 Table 63, medium density has 43: 0..42). */
#define IRQ_DMA1_CHANNEL1 11u
#define IRQ_USART1 37u
#define IRQ_COUNT 43u

static inline void nvic_enable_irq(uint32_t irq) { NVIC_ISER(irq >> 5) = 1u << (irq & 31u); }

/* PRIMASK critical section that nests (restores the previous state). */
static inline uint32_t irq_save(void)
{
    uint32_t primask;
    __asm volatile("mrs %0, primask\n cpsid i" : "=r"(primask)::"memory");
    return primask;
}
static inline void irq_restore(uint32_t primask)
{
    __asm volatile("msr primask, %0" ::"r"(primask) : "memory");
}

#endif /* STM32F103_REGS_H */
