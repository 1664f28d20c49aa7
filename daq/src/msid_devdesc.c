/* msid-device/1 as typed values (msid_devdesc.h): defaults, the checks every consumer runs, and the register
 * value codec of the Modbus channels. */
#include "msid_daq/msid_devdesc.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "msid_daq/msid_mb_proto.h"

void msid_dev_chan_defaults(msid_dev_chan *c)
{
    memset(c, 0, sizeof *c);
    c->scale = 1.0;
    c->offset = 0.0;
    c->min = c->max = c->max_step = c->safe = c->op = c->amplitude = NAN;
    c->word_order = MSID_MB_ABCD;
    c->reads_back = -1;
}

void msid_devdesc_defaults(msid_devdesc *d)
{
    memset(d, 0, sizeof *d);
    d->fc23 = -1;
    d->fade_periods = 1;
    d->clock = MSID_DEV_CLOCK_HOST;
    d->cycle_hz = NAN;
    d->rated_torque = NAN;
    d->velocity_scale = d->position_scale = 1.0;
    memcpy(d->velocity_unit, "count/s", 8);
    memcpy(d->position_unit, "count", 6);
}

uint32_t msid_dev_co_bytes(const msid_dev_chan *c)
{
    switch (c->type) {
    case MSID_DEV_INT16: case MSID_DEV_UINT16: return 2;
    case MSID_DEV_INT32: case MSID_DEV_UINT32: case MSID_DEV_FLOAT32: return 4;
    default: return 0;
    }
}

uint32_t msid_devdesc_co_pack(const msid_devdesc *d, uint8_t *tpdo_of)
{
    uint32_t k = 0, bytes = 0, n = 0;
    for (uint32_t i = 0; i < d->n_measure; ++i) {
        const uint32_t b = msid_dev_co_bytes(&d->measure[i]);
        if (bytes + b > MSID_DEV_CO_PDO_BYTES || n >= 8u) {
            if (++k >= MSID_DEV_CO_TPDOS) return 0;
            bytes = n = 0;
        }
        bytes += b;
        ++n;
        if (tpdo_of) tpdo_of[i] = (uint8_t)k;
    }
    return d->n_measure ? k + 1 : 0;
}

uint32_t msid_dev_type_regs(uint32_t t)
{
    switch (t) {
    case MSID_DEV_INT16: case MSID_DEV_UINT16: return 1;
    case MSID_DEV_INT32: case MSID_DEV_UINT32: case MSID_DEV_FLOAT32: return 2;
    case MSID_DEV_FLOAT64: return 4;
    default: return 0;
    }
}

const char *msid_dev_type_name(uint32_t t)
{
    static const char *const n[] = {NULL, "int16", "uint16", "int32", "uint32", "float32", "float64"};
    return t >= 1 && t <= MSID_DEV_FLOAT64 ? n[t] : NULL;
}

/* ---- register codec ------------------------------------------------------------------------------ */

/* The value's bytes, most significant first (n = 2, 4 or 8), into registers in word order w:
 * ABCD registers high word first, bytes high first; CDAB the registers reversed; BADC the bytes of each
 * register swapped; DCBA both. */
static void bytes_to_regs(const uint8_t *b, uint32_t n, uint32_t w, uint16_t *r)
{
    const uint32_t nr = n / 2;
    const int rev = w == MSID_MB_CDAB || w == MSID_MB_DCBA, swap = w == MSID_MB_BADC || w == MSID_MB_DCBA;
    for (uint32_t i = 0; i < nr; ++i) {
        const uint8_t hi = b[2 * i], lo = b[2 * i + 1];
        r[rev ? nr - 1 - i : i] = swap ? (uint16_t)(lo << 8 | hi) : (uint16_t)(hi << 8 | lo);
    }
}

static void regs_to_bytes(const uint16_t *r, uint32_t n, uint32_t w, uint8_t *b)
{
    const uint32_t nr = n / 2;
    const int rev = w == MSID_MB_CDAB || w == MSID_MB_DCBA, swap = w == MSID_MB_BADC || w == MSID_MB_DCBA;
    for (uint32_t i = 0; i < nr; ++i) {
        const uint16_t x = r[rev ? nr - 1 - i : i];
        b[2 * i] = (uint8_t)(swap ? x & 0xFF : x >> 8);
        b[2 * i + 1] = (uint8_t)(swap ? x >> 8 : x & 0xFF);
    }
}

static void u64_to_bytes(uint64_t v, uint32_t n, uint8_t *b)
{
    for (uint32_t i = 0; i < n; ++i) b[i] = (uint8_t)(v >> (8 * (n - 1 - i)));
}

static uint64_t bytes_to_u64(const uint8_t *b, uint32_t n)
{
    uint64_t v = 0;
    for (uint32_t i = 0; i < n; ++i) v = v << 8 | b[i];
    return v;
}

/* The representable raw range of an integer type. */
static void int_range(uint32_t t, double *lo, double *hi)
{
    switch (t) {
    case MSID_DEV_INT16: *lo = -32768.0; *hi = 32767.0; break;
    case MSID_DEV_UINT16: *lo = 0.0; *hi = 65535.0; break;
    case MSID_DEV_INT32: *lo = -2147483648.0; *hi = 2147483647.0; break;
    default: *lo = 0.0; *hi = 4294967295.0; break;
    }
}

int msid_dev_encode(const msid_dev_chan *c, double v, uint16_t *regs)
{
    const uint32_t nb = 2 * msid_dev_type_regs(c->type);
    if (!nb || !isfinite(v) || c->scale == 0) return -1;
    const double raw = (v - c->offset) / c->scale;
    uint8_t b[8] = {0};
    if (c->type == MSID_DEV_FLOAT32) {
        if (!(fabs(raw) <= 3.4028234663852886e38)) return -1;
        const float f = (float)raw;
        uint32_t u;
        memcpy(&u, &f, 4);
        u64_to_bytes(u, 4, b);
    } else if (c->type == MSID_DEV_FLOAT64) {
        if (!isfinite(raw)) return -1;
        uint64_t u;
        memcpy(&u, &raw, 8);
        u64_to_bytes(u, 8, b);
    } else {
        double lo, hi;
        int_range(c->type, &lo, &hi);
        const double q = nearbyint(raw);
        if (!(q >= lo && q <= hi)) return -1;
        const int64_t i = (int64_t)q;
        u64_to_bytes((uint64_t)i, nb, b);   /* two's complement: the low nb bytes */
    }
    bytes_to_regs(b, nb, c->word_order, regs);
    return 0;
}

double msid_dev_decode_raw(const msid_dev_chan *c, const uint16_t *regs)
{
    const uint32_t nb = 2 * msid_dev_type_regs(c->type);
    if (!nb) return NAN;
    uint8_t b[8] = {0};
    regs_to_bytes(regs, nb, c->word_order, b);
    const uint64_t u = bytes_to_u64(b, nb);
    switch (c->type) {
    case MSID_DEV_INT16: return (double)(int16_t)(uint16_t)u;
    case MSID_DEV_UINT16: return (double)(uint16_t)u;
    case MSID_DEV_INT32: return (double)(int32_t)(uint32_t)u;
    case MSID_DEV_UINT32: return (double)(uint32_t)u;
    case MSID_DEV_FLOAT32: {
        const uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, 4);
        return (double)f;
    }
    default: {
        double x;
        memcpy(&x, &u, 8);
        return x;
    }
    }
}

double msid_dev_decode(const msid_dev_chan *c, const uint16_t *regs)
{
    return msid_dev_decode_raw(c, regs) * c->scale + c->offset;
}

/* ---- checks -------------------------------------------------------------------------------------- */

static int fail(char *err, size_t cap, const char *fmt, ...)
{
    if (err && cap) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, cap, fmt, ap);
        va_end(ap);
    }
    return -1;
}

uint32_t msid_devdesc_count(const msid_devdesc *d, msid_dev_role role)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < d->n_measure; ++i) n += d->measure[i].role == (uint32_t)role;
    return n;
}

int msid_devdesc_readback(const msid_devdesc *d, uint32_t i)
{
    uint32_t k = 0;
    for (uint32_t j = 0; j < d->n_measure; ++j) {
        const msid_dev_chan *c = &d->measure[j];
        if (c->role != MSID_DEV_ROLE_INPUT) continue;
        if (c->reads_back >= 0 ? (uint32_t)c->reads_back == i : k == i) return (int)j;
        ++k;
    }
    return -1;
}

/* A value that the channel's type cannot carry (the range and the safe value are written). */
static int representable(const msid_dev_chan *c, double v)
{
    uint16_t r[4];
    return msid_dev_encode(c, v, r) == 0;
}

static int check_drive(const msid_devdesc *d, const msid_dev_chan *c, char *err, size_t cap)
{
    const char *s = d->source;
    if (!isfinite(c->safe))
        return fail(err, cap, "%s line %u: drive channel '%s' has no safe value (key safe): msid writes it on every way "
                    "out", s, c->line, c->name);
    if (!isnan(c->min) && !isnan(c->max) && !(c->min < c->max))
        return fail(err, cap, "%s line %u: drive channel '%s': min %g is not below max %g", s, c->line, c->name, c->min,
                    c->max);
    if (!isnan(c->min) && c->safe < c->min)
        return fail(err, cap, "%s line %u: drive channel '%s': the safe value %g is below min %g", s, c->line, c->name,
                    c->safe, c->min);
    if (!isnan(c->max) && c->safe > c->max)
        return fail(err, cap, "%s line %u: drive channel '%s': the safe value %g is above max %g", s, c->line, c->name,
                    c->safe, c->max);
    if (!isnan(c->max_step) && !(c->max_step > 0 && isfinite(c->max_step)))
        return fail(err, cap, "%s line %u: drive channel '%s': max_step must be positive (got %g)", s, c->line, c->name,
                    c->max_step);
    const double op = isnan(c->op) ? c->safe : c->op;
    if (!isfinite(op) || (!isnan(c->min) && op < c->min) || (!isnan(c->max) && op > c->max))
        return fail(err, cap, "%s line %u: drive channel '%s': the operating point %g is outside [min, max]", s,
                    c->line, c->name, op);
    if (!isnan(c->amplitude) && !(c->amplitude > 0 && isfinite(c->amplitude)))
        return fail(err, cap, "%s line %u: drive channel '%s': amplitude must be positive (got %g)", s, c->line,
                    c->name, c->amplitude);
    if (d->transport == MSID_DEV_CANOPEN) {
        if (!representable(c, c->safe))
            return fail(err, cap, "%s line %u: drive channel '%s': the safe value %g does not fit %s with scale %g and "
                        "offset %g (key safe)", s, c->line, c->name, c->safe, msid_dev_type_name(c->type), c->scale,
                        c->offset);
        if (!isnan(c->min) && !representable(c, c->min))
            return fail(err, cap, "%s line %u: drive channel '%s': min %g does not fit %s with scale %g and offset %g "
                        "(key min)", s, c->line, c->name, c->min, msid_dev_type_name(c->type), c->scale, c->offset);
        if (!isnan(c->max) && !representable(c, c->max))
            return fail(err, cap, "%s line %u: drive channel '%s': max %g does not fit %s with scale %g and offset %g "
                        "(key max)", s, c->line, c->name, c->max, msid_dev_type_name(c->type), c->scale, c->offset);
    }
    if (d->transport == MSID_DEV_MODBUS) {
        if (c->table != MSID_DEV_HOLDING)
            return fail(err, cap, "%s line %u: drive channel '%s' is in the input registers, which are read-only: a "
                        "drive channel needs a holding register", s, c->line, c->name);
        if (!representable(c, c->safe))
            return fail(err, cap, "%s line %u: drive channel '%s': the safe value %g does not fit %s with scale %g and "
                        "offset %g", s, c->line, c->name, c->safe, msid_dev_type_name(c->type), c->scale, c->offset);
        if (!isnan(c->min) && !representable(c, c->min))
            return fail(err, cap, "%s line %u: drive channel '%s': min %g does not fit %s with scale %g and offset %g", s,
                        c->line, c->name, c->min, msid_dev_type_name(c->type), c->scale, c->offset);
        if (!isnan(c->max) && !representable(c, c->max))
            return fail(err, cap, "%s line %u: drive channel '%s': max %g does not fit %s with scale %g and offset %g", s,
                        c->line, c->name, c->max, msid_dev_type_name(c->type), c->scale, c->offset);
    }
    return 0;
}

static int check_address(const msid_devdesc *d, const msid_dev_chan *c, char *err, size_t cap)
{
    const char *s = d->source;
    if (d->transport == MSID_DEV_MODBUS) {
        const uint32_t n = msid_dev_type_regs(c->type);
        if (!n) return fail(err, cap, "%s line %u: channel '%s' has no type", s, c->line, c->name);
        if (c->table != MSID_DEV_HOLDING && c->table != MSID_DEV_INPUT)
            return fail(err, cap, "%s line %u: channel '%s' has no register", s, c->line, c->name);
        if (c->addr + n > 65536u)
            return fail(err, cap, "%s line %u: channel '%s': register %u + %u is beyond 65535", s, c->line, c->name,
                        c->addr, n);
    } else if (d->transport == MSID_DEV_CANOPEN) {
        if (!c->co_index)
            return fail(err, cap, "%s line %u: channel '%s' needs object = \"0xINDEX:SUB\" (a CANopen channel is an "
                        "object dictionary entry)", s, c->line, c->name);
        if (!msid_dev_co_bytes(c))
            return fail(err, cap, "%s line %u: channel '%s': type must be int16, uint16, int32, uint32 or float32 (key "
                        "type: what a PDO carries of object 0x%04X:%02X)", s, c->line, c->name, c->co_index, c->co_sub);
    } else if (!c->message[0] || !c->signal[0]) {
        return fail(err, cap, "%s line %u: channel '%s' needs message and signal (a CAN channel is a DBC signal)", s,
                    c->line, c->name);
    }
    if (!(c->scale != 0 && isfinite(c->scale)) || !isfinite(c->offset))
        return fail(err, cap, "%s line %u: channel '%s': scale must be finite and non-zero, offset finite", s, c->line,
                    c->name);
    return 0;
}

/* Two Modbus channels in the same table whose registers overlap. */
static int overlap(const msid_dev_chan *a, const msid_dev_chan *b)
{
    if (a->table != b->table) return 0;
    const uint32_t ae = a->addr + msid_dev_type_regs(a->type), be = b->addr + msid_dev_type_regs(b->type);
    return a->addr < be && b->addr < ae;
}

int msid_devdesc_check(const msid_devdesc *d, char *err, size_t cap)
{
    const char *s = d->source;
    if (d->transport != MSID_DEV_MODBUS && d->transport != MSID_DEV_CAN && d->transport != MSID_DEV_CANOPEN)
        return fail(err, cap, "%s: transport must be \"modbus\", \"can\" or \"canopen\"", s);
    if (d->n_drive == 0) return fail(err, cap, "%s: no [[drive]] channel: msid needs one to excite the device", s);
    if (d->n_drive > MSID_DEV_MAX_DRIVE || d->n_measure > MSID_DEV_MAX_MEASURE)
        return fail(err, cap, "%s: at most %u drive and %u measure channels", s, MSID_DEV_MAX_DRIVE,
                    MSID_DEV_MAX_MEASURE);
    if (msid_devdesc_count(d, MSID_DEV_ROLE_OUTPUT) == 0)
        return fail(err, cap, "%s: no [[measure]] channel with role = \"output\"", s);
    if (d->fade_periods > 8) return fail(err, cap, "%s: fade_periods must be 0..8 (got %u)", s, d->fade_periods);
    const uint32_t nall = d->n_drive + d->n_measure;
    for (uint32_t i = 0; i < nall; ++i) {
        const msid_dev_chan *c = i < d->n_drive ? &d->drive[i] : &d->measure[i - d->n_drive];
        if (!c->name[0]) return fail(err, cap, "%s line %u: a channel without a name", s, c->line);
        if (check_address(d, c, err, cap)) return -1;
        if (i < d->n_drive && check_drive(d, c, err, cap)) return -1;
        if (i >= d->n_drive && (c->role < MSID_DEV_ROLE_INPUT || c->role > MSID_DEV_ROLE_COUNTER))
            return fail(err, cap, "%s line %u: measure channel '%s' needs a role: input, output, reference or counter",
                        s, c->line, c->name);
        for (uint32_t j = 0; j < i; ++j) {
            const msid_dev_chan *o = j < d->n_drive ? &d->drive[j] : &d->measure[j - d->n_drive];
            if (!strcmp(o->name, c->name))
                return fail(err, cap, "%s line %u: a second channel named '%s' (line %u)", s, c->line, c->name, o->line);
            if (d->transport == MSID_DEV_MODBUS && overlap(o, c))
                return fail(err, cap, "%s line %u: channel '%s' overlaps the registers of '%s' (line %u)", s, c->line,
                            c->name, o->name, o->line);
        }
    }
    const uint32_t nin = msid_devdesc_count(d, MSID_DEV_ROLE_INPUT);
    if (nin && nin != d->n_drive)
        return fail(err, cap, "%s: %u input channel(s) read back %u drive channel(s): read back every drive channel "
                    "or none (the FRF needs one input per drive channel)", s, nin, d->n_drive);
    for (uint32_t i = 0; i < d->n_measure; ++i) {
        const msid_dev_chan *c = &d->measure[i];
        if (c->role == MSID_DEV_ROLE_INPUT && c->reads_back >= (int32_t)d->n_drive)
            return fail(err, cap, "%s line %u: input channel '%s' reads back a drive channel that does not exist", s,
                        c->line, c->name);
    }
    for (uint32_t i = 0; nin && i < d->n_drive; ++i) {
        int found = 0;
        for (uint32_t j = 0, k = 0; j < d->n_measure; ++j) {
            const msid_dev_chan *c = &d->measure[j];
            if (c->role != MSID_DEV_ROLE_INPUT) continue;
            found += c->reads_back >= 0 ? (uint32_t)c->reads_back == i : k == i;
            ++k;
        }
        if (found != 1)
            return fail(err, cap, "%s: drive channel '%s' is read back by %d input channels: give each input channel "
                        "reads_back = \"<drive name>\"", s, d->drive[i].name, found);
    }
    for (uint32_t i = 0; i < d->n_measure; ++i) {
        const msid_dev_chan *c = &d->measure[i];
        if (c->role == MSID_DEV_ROLE_COUNTER &&
            (c->scale != 1.0 || c->offset != 0.0 ||
             (d->transport == MSID_DEV_MODBUS && (c->type == MSID_DEV_FLOAT32 || c->type == MSID_DEV_FLOAT64))))
            return fail(err, cap, "%s line %u: counter channel '%s' counts cycles: an integer register, scale 1 and "
                        "offset 0", s, c->line, c->name);
    }
    if (msid_devdesc_count(d, MSID_DEV_ROLE_COUNTER) > 1)
        return fail(err, cap, "%s: more than one channel with role = \"counter\"", s);
    if (d->transport == MSID_DEV_CANOPEN) {
        if (d->co_mode != 8 && d->co_mode != 9 && d->co_mode != 10)
            return fail(err, cap, "%s: a CANopen drive runs in a cyclic synchronous mode: give preset = \"cst\", "
                        "\"csv\" or \"csp\", or mode = ... with explicit channels (key mode)", s);
        uint32_t bytes = 0;
        for (uint32_t i = 0; i < d->n_drive; ++i) bytes += msid_dev_co_bytes(&d->drive[i]);
        if (bytes > MSID_DEV_CO_PDO_BYTES)
            return fail(err, cap, "%s: the drive channels map %u bytes (key object of each [[drive]]): the one RPDO "
                        "msid writes each SYNC carries at most %u", s, bytes, MSID_DEV_CO_PDO_BYTES);
        if (!msid_devdesc_co_pack(d, NULL)) {
            bytes = 0;
            for (uint32_t i = 0; i < d->n_measure; ++i) bytes += msid_dev_co_bytes(&d->measure[i]);
            return fail(err, cap, "%s: the measure channels map %u bytes in %u objects (key object of each "
                        "[[measure]]): msid maps them into two TPDOs of at most %u bytes and 8 objects each, packed "
                        "in order", s, bytes, d->n_measure, MSID_DEV_CO_PDO_BYTES);
        }
        if (d->clock == MSID_DEV_CLOCK_DEVICE)
            return fail(err, cap, "%s: clock = \"device\" is not for CANopen: msid's SYNC is the node's clock", s);
        if (!isnan(d->rated_torque) && !(d->rated_torque > 0 && isfinite(d->rated_torque)))
            return fail(err, cap, "%s: rated_torque must be positive (N m)", s);
        if (!(d->velocity_scale != 0 && isfinite(d->velocity_scale)) ||
            !(d->position_scale != 0 && isfinite(d->position_scale)))
            return fail(err, cap, "%s: velocity_scale and position_scale must be finite and non-zero", s);
        if (d->co_closed_loop == 2) {
            const double counts = d->co_hold_velocity / d->velocity_scale;
            if (!(fabs(counts) <= 2147483647.0))
                return fail(err, cap, "%s: hold_velocity %g %s is %g counts of 0x60FF at velocity_scale %g: "
                            "outside INTEGER32", s, d->co_hold_velocity, d->velocity_unit, counts, d->velocity_scale);
        }
    }
    if (d->clock == MSID_DEV_CLOCK_DEVICE && msid_devdesc_count(d, MSID_DEV_ROLE_COUNTER) == 0)
        return fail(err, cap, "%s: clock = \"device\" needs a channel with role = \"counter\" (the device's cycle "
                    "counter paces the ticks)", s);
    return 0;
}
