#include "mbap.h"

#define MBAP_MIN_LENGTH 2u   /* unit id + function code */
#define MBAP_MAX_LENGTH 254u /* unit id + the largest PDU */

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)((p[0] << 8) | p[1]);
}

int mbap_frame_length(const uint8_t *buf, size_t len)
{
    if (len < MBAP_HEADER_LEN)
        return 0;
    uint16_t protocol = be16(buf + 2), length = be16(buf + 4);
    if (protocol != 0 || length < MBAP_MIN_LENGTH || length > MBAP_MAX_LENGTH)
        return -1;
    if (len > MBAP_HEADER_LEN && (buf[MBAP_HEADER_LEN] & 0x7Fu) == 0)
        return -1;
    size_t frame = 6u + length;
    return len < frame ? 0 : (int)frame;
}

size_t mbap_wrap_response(const uint8_t *req, uint8_t *rsp, size_t pdu_len)
{
    rsp[0] = req[0]; /* transaction id */
    rsp[1] = req[1];
    rsp[2] = 0;      /* protocol id */
    rsp[3] = 0;
    rsp[4] = (uint8_t)((pdu_len + 1u) >> 8); /* unit id + PDU */
    rsp[5] = (uint8_t)((pdu_len + 1u) & 0xFFu);
    rsp[6] = req[6]; /* unit id */
    return MBAP_HEADER_LEN + pdu_len;
}

size_t mbap_exception_response(const uint8_t *req, uint8_t code, uint8_t *rsp)
{
    size_t pdu_len = leveler_modbus_pdu_exception(req[MBAP_HEADER_LEN], code, rsp + MBAP_HEADER_LEN);
    return mbap_wrap_response(req, rsp, pdu_len);
}
