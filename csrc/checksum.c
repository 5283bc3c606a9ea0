/* ARCOS checksum: big-endian 16-bit pair sums modulo 65536, odd last byte XORed. */
#include "robocli_core.h"

unsigned int rc_arcos_checksum(const unsigned char *data, size_t n)
{
    unsigned int c = 0;
    size_t i = 0;

    while (n - i > 1) {
        c = (c + (((unsigned int)data[i] << 8) | (unsigned int)data[i + 1])) & 0xFFFFu;
        i += 2;
    }
    if (n - i == 1) {
        c ^= (unsigned int)data[i];
    }
    return c & 0xFFFFu;
}
