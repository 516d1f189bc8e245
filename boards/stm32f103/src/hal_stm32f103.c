/*
 * leveler/hal.h on the STM32F103: GPIO outputs, ADC1 scan by circular DMA with
 * 16x oversampling, USART1 Modbus RTU link with an RS-485 driver enable.
 */
#include "leveler/hal.h"

#include "board.h"
#include "board_logic.h"
#include "byte_ring.h"
#include "stm32f103_regs.h"

/* ---------------- Digital outputs ---------------- */

static volatile bool s_firmware_led_request;

void hal_output_set(hal_output output, bool on)
{
    /* BSRR/BRR writes are atomic, so this is safe from any context, and before
     * hal init (the GPIO clocks are switched on first thing in reset). */
    if (output < HAL_OUT_STATUS_LED) {
        uint32_t mask = 1u << (BOARD_OUT_PORT_PINS_FIRST + (uint32_t)output);
        if (on) {
            GPIOB->BSRR = mask;
        } else {
            GPIOB->BRR = mask;
        }
    } else if (output == HAL_OUT_STATUS_LED) {
        /* main.c owns the pin: it shows this request unless a fault blink
         * code is due. */
        s_firmware_led_request = on;
    }
}

bool board_firmware_led_request(void) { return s_firmware_led_request; }

void board_led_set(bool lit)
{
    if (lit) {
        GPIOC->BRR = 1u << BOARD_LED_PIN; /* active low */
    } else {
        GPIOC->BSRR = 1u << BOARD_LED_PIN;
    }
}

/* ---------------- ADC1 + DMA1 channel 1 ----------------
 * Continuous scan of IN0..IN3, 239.5-cycle sampling (for the ~10 kOhm divider
 * source, RM0008 11.6 / DS5319 R_AIN), 12.5 cycles conversion: 252 ADC clocks
 * = 21 us per channel at 12 MHz. The circular DMA buffer holds 16 scans, so a
 * full buffer (one "scan set") completes every 64 x 21 us = 1.34 ms. */
#define ADC_SAMPLES_PER_CHANNEL 16u
#define ADC_BUFFER_LEN (ADC_SAMPLES_PER_CHANNEL * (uint32_t)HAL_ADC_COUNT)
/* A reading is stale if no scan set completed within this long (several
 * periods, allowing for the flash-erase stall of interrupts). */
#define ADC_STALE_MS 50u

static volatile uint16_t s_adc_buffer[ADC_BUFFER_LEN];
static volatile uint32_t s_adc_last_complete_ms;
static volatile bool s_adc_ever_complete;
static volatile bool s_adc_dma_error;

void DMA1_Channel1_IRQHandler(void)
{
    uint32_t isr = DMA1->ISR;
    DMA1->IFCR = DMA_IFCR_CGIF1;
    if (isr & DMA_ISR_TEIF1) {
        s_adc_dma_error = true; /* the channel is disabled by hardware: stays stale */
    }
    if (isr & DMA_ISR_TCIF1) {
        s_adc_last_complete_ms = hal_now_ms();
        s_adc_ever_complete = true;
    }
}

static void adc_init(void)
{
    RCC->APB2ENR |= RCC_APB2ENR_ADC1EN;
    RCC->AHBENR |= RCC_AHBENR_DMA1EN;
    /* PA0..PA3 analog. */
    GPIOA->CRL = (GPIOA->CRL & ~0xFFFFu) | 0x0000u;

    dma_channel_regs *ch = &DMA1->CH[0];
    ch->CCR = 0;
    ch->CPAR = (uint32_t)(uintptr_t)&ADC1->DR;
    ch->CMAR = (uint32_t)(uintptr_t)s_adc_buffer;
    ch->CNDTR = ADC_BUFFER_LEN;
    ch->CCR = DMA_CCR_PL_HIGH | DMA_CCR_MSIZE_16 | DMA_CCR_PSIZE_16 | DMA_CCR_MINC | DMA_CCR_CIRC |
              DMA_CCR_TEIE | DMA_CCR_TCIE | DMA_CCR_EN;
    nvic_enable_irq(IRQ_DMA1_CHANNEL1);

    ADC1->CR1 = ADC_CR1_SCAN;
    uint32_t smpr2 = 0;
    for (uint32_t channel = 0; channel < (uint32_t)HAL_ADC_COUNT; channel++) {
        smpr2 |= ADC_SMP_239_5 << (3u * channel);
    }
    ADC1->SMPR2 = smpr2;
    ADC1->SQR1 = ((uint32_t)HAL_ADC_COUNT - 1u) << ADC_SQR1_L_POS;
    ADC1->SQR3 = (0u << 0) | (1u << 5) | (2u << 10) | (3u << 15); /* IN0, IN1, IN2, IN3 */
    ADC1->SQR2 = 0;

    /* Power up, then calibrate (RM0008 11.4: ADON >= 2 ADC clocks before CAL). */
    ADC1->CR2 = ADC_CR2_ADON;
    for (volatile uint32_t i = 0; i < 1000u; i++) {
    }
    ADC1->CR2 = ADC_CR2_ADON | ADC_CR2_RSTCAL;
    for (uint32_t i = 0; i < 100000u && (ADC1->CR2 & ADC_CR2_RSTCAL); i++) {
    }
    ADC1->CR2 = ADC_CR2_ADON | ADC_CR2_CAL;
    for (uint32_t i = 0; i < 100000u && (ADC1->CR2 & ADC_CR2_CAL); i++) {
    }
    ADC1->CR2 = ADC_CR2_ADON | ADC_CR2_CONT | ADC_CR2_DMA | ADC_CR2_EXTSEL_SWSTART | ADC_CR2_EXTTRIG;
    ADC1->CR2 |= ADC_CR2_SWSTART;
}

bool hal_adc_read(hal_adc_channel channel, uint16_t *counts)
{
    if ((uint32_t)channel >= (uint32_t)HAL_ADC_COUNT || counts == NULL) {
        return false;
    }
    if (!s_adc_ever_complete || s_adc_dma_error ||
        (uint32_t)(hal_now_ms() - s_adc_last_complete_ms) > ADC_STALE_MS) {
        return false;
    }
    /* The DMA keeps overwriting the buffer while we sum: each element is one
     * whole conversion no older than one scan set, which is all a mean needs. */
    *counts = adc_oversample_mean(s_adc_buffer, (uint32_t)channel, (uint32_t)HAL_ADC_COUNT,
                                  ADC_SAMPLES_PER_CHANNEL);
    return true;
}

/* ---------------- USART1 + RS-485 ----------------
 * 8 data bits + even parity = 9-bit word (M=1, PCE=1, PS=0), 1 stop bit.
 * RX: RXNE interrupt into a ring. TX: ring drained by TXE; DE (PA8) goes high
 * when a write starts and low on TC after the last stop bit. */
static byte_ring s_rx_ring;
static byte_ring s_tx_ring;
static volatile bool s_tx_active;
static volatile uint32_t s_serial_errors; /* parity/framing/noise/overrun, or RX ring full */

void USART1_IRQHandler(void)
{
    uint32_t sr = USART1->SR;
    if (sr & (USART_SR_RXNE | USART_SR_ORE)) {
        uint8_t byte = (uint8_t)USART1->DR; /* SR then DR read clears the flags */
        if (sr & (USART_SR_PE | USART_SR_FE | USART_SR_NE | USART_SR_ORE)) {
            s_serial_errors++; /* a damaged byte is dropped: the frame's CRC then fails */
        } else if (!byte_ring_put(&s_rx_ring, byte)) {
            s_serial_errors++;
        }
    }
    uint32_t cr1 = USART1->CR1;
    if ((cr1 & USART_CR1_TXEIE) && (sr & USART_SR_TXE)) {
        uint8_t byte;
        if (byte_ring_get(&s_tx_ring, &byte)) {
            USART1->DR = byte;
        } else {
            USART1->CR1 = (cr1 & ~USART_CR1_TXEIE) | USART_CR1_TCIE;
        }
    } else if ((cr1 & USART_CR1_TCIE) && (sr & USART_SR_TC)) {
        USART1->CR1 = cr1 & ~USART_CR1_TCIE;
        GPIOA->BRR = 1u << BOARD_DE_PIN; /* last stop bit is out: release the bus */
        s_tx_active = false;
    }
}

static void usart_init(void)
{
    RCC->APB2ENR |= RCC_APB2ENR_USART1EN | RCC_APB2ENR_AFIOEN;
    /* PA9 TX alternate push-pull; PA10 RX input with pull-up (the transceiver's
     * RO floats while DE/RE is high). */
    uint32_t crh = GPIOA->CRH;
    crh = (crh & ~(0xFu << 4)) | (GPIO_CFG_AF_PP_50MHZ << 4);
    crh = (crh & ~(0xFu << 8)) | (GPIO_CFG_INPUT_PULL << 8);
    GPIOA->CRH = crh;
    GPIOA->BSRR = 1u << 10;

    byte_ring_init(&s_rx_ring);
    byte_ring_init(&s_tx_ring);
    USART1->CR2 = 0; /* 1 stop bit */
    USART1->CR3 = 0;
    (void)board_serial_set_baud(19200u);
    USART1->CR1 = USART_CR1_UE | USART_CR1_M_9BIT | USART_CR1_PCE | USART_CR1_TE | USART_CR1_RE |
                  USART_CR1_RXNEIE;
    nvic_enable_irq(IRQ_USART1);
}

static uint32_t s_baud;

bool board_serial_set_baud(uint32_t baud)
{
    uint16_t brr = usart_brr(board_clock()->pclk2_hz, baud);
    if (brr == 0u) {
        return false;
    }
    USART1->BRR = brr; /* only written while the line is idle (main.c checks) */
    s_baud = baud;
    return true;
}

void board_serial_reclock(void)
{
    uint16_t brr = usart_brr(board_clock()->pclk2_hz, s_baud);
    if (brr != 0u) {
        USART1->BRR = brr;
    }
}

bool board_serial_idle(void) { return !s_tx_active && byte_ring_used(&s_tx_ring) == 0u; }

size_t hal_serial_read(uint8_t *buf, size_t max_len)
{
    return byte_ring_read(&s_rx_ring, buf, max_len);
}

size_t hal_serial_write(const uint8_t *buf, size_t len)
{
    size_t n = byte_ring_write(&s_tx_ring, buf, len);
    if (n > 0u) {
        uint32_t primask = irq_save(); /* CR1 is also changed by the ISR */
        s_tx_active = true;
        GPIOA->BSRR = 1u << BOARD_DE_PIN;
        USART1->CR1 = (USART1->CR1 & ~USART_CR1_TCIE) | USART_CR1_TXEIE;
        irq_restore(primask);
    }
    return n;
}

void board_hal_init(void)
{
    adc_init();
    usart_init();
}

/* ---- the time base: 1 ms SysTick behind hal_now_ms, one owner ---- */
static volatile uint32_t s_now_ms;

void SysTick_Handler(void) { s_now_ms++; }

uint32_t hal_now_ms(void) { return s_now_ms; } /* aligned 32-bit load: atomic */

void board_systick_init(void)
{
    /* 24-bit reload: 72e6/1000 - 1 = 71999 fits. */
    SYSTICK->LOAD = board_clock()->sysclk_hz / 1000u - 1u;
    SYSTICK->VAL = 0;
    SYSTICK->CTRL = SYSTICK_CTRL_CLKSOURCE_CPU | SYSTICK_CTRL_TICKINT | SYSTICK_CTRL_ENABLE;
}

/* Clock security: after the switch to HSI, re-time what depends on the clock. */
void NMI_Handler(void)
{
    if (board_clock_recover_after_css()) {
        board_systick_init();
        board_serial_reclock();
        return;
    }
    Default_Handler();
}
