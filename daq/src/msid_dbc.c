/* DBC files: a reader into caller memory and the signal codec.
 *
 * One parser runs in three modes over the text: COUNT sizes the tables (and
 * checks the syntax), PLACE fills messages, signals and names, ATTR applies the
 * statements that refer to messages by identifier (cycle times, float types),
 * which a DBC may write before or after them. The tables are laid out once from
 * the counts (layout()), so the size and the placement cannot drift apart. */
#include "msid_daq/msid_dbc.h"

#include <float.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { COUNT, PLACE, ATTR };

/* VECTOR__INDEPENDENT_SIG_MSG (signals of no message): skipped, as cantools does. */
static const char INDEPENDENT[] = "VECTOR__INDEPENDENT_SIG_MSG";
static const char CYCLE[] = "GenMsgCycleTime";
/* The mux value of a bare 'm' indicator (no value), until the message is known to have no switch. */
#define BARE_M 0xFFFFFFFFu

/* Sections of the format that are ';'-terminated and carry nothing msid uses. */
static const char *const SKIPPED[] = {
    "CM_", "VAL_", "VAL_TABLE_", "EV_", "ENVVAR_DATA_", "SGTYPE_", "SGTYPE_VAL_", "SIG_GROUP_", "SIG_TYPE_REF_",
    "SIGTYPE_VALTYPE_", "BO_TX_BU_", "BU_SG_REL_", "BU_EV_REL_", "BU_BO_REL_", "BA_DEF_REL_", "BA_REL_",
    "BA_DEF_DEF_REL_", "BA_DEF_SGTYPE_", "BA_SGTYPE_", "CAT_DEF_", "CAT_", "FILTER", "NS_DESC_", "EV_DATA_",
    "ENVVAR_DATA_", "BA_DEF_REL_"};

typedef struct parser {
    const char *p, *end;
    uint32_t line;
    int mode;
    msid_dbc *d;
    /* COUNT: the sizes */
    uint32_t n_msg, n_sig;
    size_t n_str;
    /* PLACE: where the next message, signal and name go */
    char *str;
    int32_t cur;          /* message the SG_ lines belong to (-1: none; -2: a skipped message) */
    int cycle_defined;    /* a BA_DEF_ defines GenMsgCycleTime */
    uint32_t cycle_default;
    uint32_t err_line;
    char err[224];
} parser;

/* ---- the first problem, with its line ---- */

static int fail(parser *ps, uint32_t line, const char *fmt, ...)
{
    if (ps->err[0]) return -MSID_DAQ_E_FORMAT;
    va_list ap;
    va_start(ap, fmt);
    int n = snprintf(ps->err, sizeof ps->err, "line %u: ", (unsigned)line);
    if (n < 0) n = 0;
    if ((size_t)n < sizeof ps->err) vsnprintf(ps->err + n, sizeof ps->err - (size_t)n, fmt, ap);
    va_end(ap);
    ps->err_line = line;
    return -MSID_DAQ_E_FORMAT;
}

/* ---- the cursor ---- */

static void blanks(parser *ps)   /* spaces and tabs, not line ends; a // comment runs to the line end */
{
    while (ps->p < ps->end && (*ps->p == ' ' || *ps->p == '\t' || *ps->p == '\r')) ++ps->p;
    if (ps->p + 1 < ps->end && ps->p[0] == '/' && ps->p[1] == '/')
        while (ps->p < ps->end && *ps->p != '\n') ++ps->p;
}

static void space(parser *ps)   /* blanks, line ends and // comments (to the end of their line) */
{
    while (ps->p < ps->end) {
        if (*ps->p == '/' && ps->p + 1 < ps->end && ps->p[1] == '/') {
            while (ps->p < ps->end && *ps->p != '\n') ++ps->p;
            continue;
        }
        if (*ps->p != ' ' && *ps->p != '\t' && *ps->p != '\r' && *ps->p != '\n') return;
        if (*ps->p == '\n') ps->line++;
        ++ps->p;
    }
}

static int at_eol(parser *ps)
{
    blanks(ps);
    return ps->p >= ps->end || *ps->p == '\n';
}

static int name_char(char c)
{
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
}

/* A name ([A-Za-z0-9_]+) after blanks (and line ends when `lines`); its length, 0 if none. */
static size_t word(parser *ps, const char **s, int lines)
{
    if (lines) space(ps);
    else blanks(ps);
    const char *b = ps->p;
    while (ps->p < ps->end && name_char(*ps->p)) ++ps->p;
    *s = b;
    return (size_t)(ps->p - b);
}

static int is(const char *s, size_t n, const char *kw) { return strlen(kw) == n && !memcmp(s, kw, n); }

static int expect(parser *ps, char c, const char *what)
{
    blanks(ps);
    if (ps->p >= ps->end || *ps->p != c) {
        const char *got = ps->p >= ps->end ? "the end of the file" : *ps->p == '\n' ? "the end of the line" : NULL;
        if (got) return fail(ps, ps->line, "expected '%c' %s, found %s", c, what, got);
        return fail(ps, ps->line, "expected '%c' %s, found '%c'", c, what, *ps->p);
    }
    ++ps->p;
    return 0;
}

/* An unsigned decimal integer below 2^32. */
static int uint_(parser *ps, uint32_t *v, const char *what)
{
    blanks(ps);
    uint64_t x = 0;
    const char *b = ps->p;
    while (ps->p < ps->end && *ps->p >= '0' && *ps->p <= '9') {
        x = x * 10u + (uint64_t)(*ps->p++ - '0');
        if (x > 0xFFFFFFFFu) return fail(ps, ps->line, "%s is too large", what);
    }
    if (ps->p == b) return fail(ps, ps->line, "expected %s (an unsigned integer)", what);
    *v = (uint32_t)x;
    return 0;
}

/* A decimal number ([+-]digits[.digits][e[+-]digits]) as strtod reads it in the C locale: the token is
 * copied and its '.' becomes the locale's decimal point, so a caller's setlocale() cannot change it. */
static int number(parser *ps, double *v, const char *what)
{
    blanks(ps);
    char buf[80];
    size_t n = 0;
    const char *b = ps->p;
    while (ps->p < ps->end && n + 1 < sizeof buf &&
           ((*ps->p >= '0' && *ps->p <= '9') || *ps->p == '.' || *ps->p == '+' || *ps->p == '-' || *ps->p == 'e' ||
            *ps->p == 'E'))
        buf[n++] = *ps->p++;
    buf[n] = 0;
    if (n == 0) return fail(ps, ps->line, "expected %s (a number)", what);
    const struct lconv *lc = localeconv();
    const char dp = lc && lc->decimal_point && lc->decimal_point[0] ? lc->decimal_point[0] : '.';
    if (dp != '.')
        for (size_t k = 0; k < n; ++k)
            if (buf[k] == '.') buf[k] = dp;
    char *e = NULL;
    const double x = strtod(buf, &e);
    if (e != buf + n || !isfinite(x)) {
        ps->p = b;
        return fail(ps, ps->line, "%s '%.40s' is not a finite number", what, buf);
    }
    *v = x;
    return 0;
}

/* A quoted string ("..." with \" and \\ escapes, line ends allowed). The content's start and raw length. */
static int quoted(parser *ps, const char **s, size_t *n, int lines)
{
    if (lines) space(ps);
    else blanks(ps);
    const uint32_t l0 = ps->line;
    if (ps->p >= ps->end || *ps->p != '"') return fail(ps, ps->line, "expected a quoted string");
    *s = ++ps->p;
    while (ps->p < ps->end && *ps->p != '"') {
        if (*ps->p == '\\' && ps->p + 1 < ps->end) ++ps->p;
        if (*ps->p == '\n') ps->line++;
        ++ps->p;
    }
    if (ps->p >= ps->end) return fail(ps, l0, "a quoted string is not closed");
    *n = (size_t)(ps->p - *s);
    ++ps->p;
    return 0;
}

/* Up to and past the ';' that ends a statement begun on line l0 (strings may hold ';' and line ends). */
static int to_semicolon(parser *ps, uint32_t l0, const char *kw, size_t kwn)
{
    while (ps->p < ps->end) {
        if (*ps->p == '"') {
            const char *s;
            size_t n;
            int rc = quoted(ps, &s, &n, 0);
            if (rc) return rc;
            continue;
        }
        if (*ps->p == '\n') ps->line++;
        if (*ps->p++ == ';') return 0;
    }
    return fail(ps, l0, "the %.*s statement is not ended by ';'", (int)kwn, kw);
}

static void to_eol(parser *ps)
{
    while (ps->p < ps->end && *ps->p != '\n') ++ps->p;
}

static int end_of_line(parser *ps, const char *what)
{
    if (at_eol(ps)) return 0;
    return fail(ps, ps->line, "unexpected '%c' after %s", *ps->p, what);
}

/* ---- the arena's names ---- */

/* Count (COUNT) or copy (PLACE) a name; \" and \\ lose their backslash. */
static const char *keep(parser *ps, const char *s, size_t n)
{
    if (ps->mode == COUNT) {
        ps->n_str += n + 1;
        return "";
    }
    if (ps->mode != PLACE) return "";
    char *o = ps->str, *w = o;
    for (size_t k = 0; k < n; ++k) {
        if (s[k] == '\\' && k + 1 < n && (s[k + 1] == '"' || s[k + 1] == '\\')) ++k;
        *w++ = s[k];
    }
    *w++ = 0;
    ps->str = w;
    return o;
}

/* ---- identifiers ---- */

/* The DBC's identifier (bit 31: extended) as msid stores it; 0 when it is out of range. */
static int can_id(uint32_t dbc, uint32_t *id)
{
    if (dbc & 0x80000000u) {
        if (dbc & 0x60000000u) return 0;
        *id = (dbc & 0x1FFFFFFFu) | MSID_CAN_EFF_FLAG;
        return 1;
    }
    if (dbc > 0x7FFu) return 0;
    *id = dbc;
    return 1;
}

static msid_dbc_message *find_dbc_id(parser *ps, uint32_t dbc)
{
    uint32_t id;
    if (!can_id(dbc, &id)) return NULL;
    return (msid_dbc_message *)(uintptr_t)msid_dbc_message_by_id(ps->d, id);
}

/* ---- the statements ---- */

/* NS_ : the list of keywords the file may use, one per line: it ends at a word followed on its line by
 * ':' or a number (BS_:, BU_:, BO_ 100 ...) or by anything but the line end. */
static int st_ns(parser *ps)
{
    int rc = expect(ps, ':', "after NS_");
    if (rc) return rc;
    for (;;) {
        const char *save = ps->p;
        const uint32_t line = ps->line;
        const char *s;
        const size_t n = word(ps, &s, 1);
        if (n == 0 || !at_eol(ps)) {
            ps->p = save;
            ps->line = line;
            return 0;
        }
    }
}

static int keyword(const char *s, size_t n);

/* BU_: the nodes, to the end of the line and on the lines after it that start with a name which is
 * not a keyword (some files list one node per line). */
static int st_bu(parser *ps)
{
    int rc = expect(ps, ':', "after BU_");
    if (rc) return rc;
    for (;;) {
        to_eol(ps);
        const char *save = ps->p;
        const uint32_t line = ps->line;
        const char *s;
        const size_t n = word(ps, &s, 1);
        if (n == 0 || keyword(s, n)) {
            ps->p = save;
            ps->line = line;
            return 0;
        }
    }
}

static int st_bo(parser *ps, uint32_t l0)
{
    uint32_t dbc_id, dlc, id = 0;
    const char *name, *sender = "";
    size_t nn, ns = 0;
    int rc = uint_(ps, &dbc_id, "the message identifier");
    if (rc) return rc;
    if ((nn = word(ps, &name, 0)) == 0) return fail(ps, ps->line, "expected the message name after BO_ %u", (unsigned)dbc_id);
    if ((rc = expect(ps, ':', "after the message name")) != 0) return rc;
    if ((rc = uint_(ps, &dlc, "the message length in bytes")) != 0) return rc;
    if (!at_eol(ps)) {
        if ((ns = word(ps, &sender, 0)) == 0) return fail(ps, ps->line, "expected the sending node after the length");
        if ((rc = end_of_line(ps, "the sending node")) != 0) return rc;
    }
    if (is(name, nn, INDEPENDENT)) {
        ps->cur = -2;   /* its signals are skipped with it */
        return 0;
    }
    if (!can_id(dbc_id, &id)) {
        if (dbc_id & 0x80000000u)
            return fail(ps, l0, "message %.*s: extended identifier 0x%X is beyond 0x1FFFFFFF", (int)nn, name,
                        (unsigned)(dbc_id & 0x7FFFFFFFu));
        return fail(ps, l0, "message %.*s: standard identifier 0x%X is beyond 0x7FF (an extended one has bit 31 set)",
                    (int)nn, name, (unsigned)dbc_id);
    }
    if (dlc > MSID_DBC_MAX_DLC)
        return fail(ps, l0, "message %.*s: %u bytes is longer than a CAN FD frame (64)", (int)nn, name, (unsigned)dlc);
    if (ps->mode == COUNT) {
        if (ps->n_msg == UINT32_MAX / 2) return fail(ps, l0, "too many messages");
        ps->n_msg++;
        keep(ps, name, nn);
        keep(ps, sender, ns);
        ps->cur = 0;   /* its SG_ lines are counted */
        return 0;
    }
    if (ps->mode == ATTR) {
        ps->cur = 0;
        return 0;
    }
    msid_dbc *d = ps->d;
    msid_dbc_message *m = &d->messages[d->n_messages];
    m->name = keep(ps, name, nn);
    m->sender = keep(ps, sender, ns);
    m->id = id;
    m->dlc = dlc;
    m->cycle_ms = 0;
    m->line = l0;
    m->first_signal = d->n_signals;
    m->n_signals = 0;
    m->mux_signal = -1;
    ps->cur = (int32_t)d->n_messages++;
    return 0;
}

/* The multiplexer indicator of an SG_: "" none, "M" the switch, "m<N>" multiplexed, "m<N>M" extended. */
static int mux_field(parser *ps, const char *s, size_t n, uint8_t *role, uint32_t *value)
{
    *role = MSID_DBC_PLAIN;
    *value = 0;
    if (n == 0) return 0;
    if (n == 1 && s[0] == 'M') {
        *role = MSID_DBC_SWITCH;
        return 0;
    }
    if (n == 1 && s[0] == 'm') {   /* no value: read as cantools does, plain where the message has no switch */
        *role = MSID_DBC_MUXED;
        *value = BARE_M;
        return 0;
    }
    if (s[0] != 'm' || n < 2) return fail(ps, ps->line, "'%.*s' is not a multiplexer indicator (M or m<N>)", (int)n, s);
    uint64_t v = 0;
    size_t k = 1;
    for (; k < n && s[k] >= '0' && s[k] <= '9'; ++k) {
        v = v * 10u + (uint64_t)(s[k] - '0');
        if (v > 0xFFFFFFFFu) return fail(ps, ps->line, "multiplexer value '%.*s' is too large", (int)n, s);
    }
    if (k == 1) return fail(ps, ps->line, "'%.*s' is not a multiplexer indicator (M or m<N>)", (int)n, s);
    if (v == BARE_M) return fail(ps, ps->line, "multiplexer value '%.*s' is too large", (int)n, s);
    if (k + 1 == n && s[k] == 'M')
        return fail(ps, ps->line,
                    "'%.*s': extended multiplexing (a multiplexed switch) is not supported: msid reads simple "
                    "multiplexing only",
                    (int)n, s);
    if (k != n) return fail(ps, ps->line, "'%.*s' is not a multiplexer indicator (M or m<N>)", (int)n, s);
    *role = MSID_DBC_MUXED;
    *value = (uint32_t)v;
    return 0;
}

/* Position of DBC bit b in MSB-first numbering (byte b/8, bit 7 - b%8): Motorola signals run upwards in it. */
static uint32_t msb_pos(uint32_t b) { return b / 8u * 8u + 7u - b % 8u; }

static uint32_t last_byte(uint32_t start, uint32_t length, int order)
{
    return order == MSID_DBC_INTEL ? (start + length - 1u) / 8u : (msb_pos(start) + length - 1u) / 8u;
}

static int st_sg(parser *ps, uint32_t l0)
{
    const char *name, *mx, *unit;
    size_t nn, nm, nu;
    uint32_t start, length, order_c;
    uint8_t role;
    uint32_t mux_value;
    double factor, offset, lo, hi;
    int rc;
    if ((nn = word(ps, &name, 0)) == 0) return fail(ps, ps->line, "expected the signal name after SG_");
    nm = word(ps, &mx, 0);
    if ((rc = mux_field(ps, mx, nm, &role, &mux_value)) != 0) return rc;
    if ((rc = expect(ps, ':', "after the signal name")) != 0) return rc;
    if ((rc = uint_(ps, &start, "the start bit")) != 0) return rc;
    if ((rc = expect(ps, '|', "after the start bit")) != 0) return rc;
    if ((rc = uint_(ps, &length, "the signal length")) != 0) return rc;
    if ((rc = expect(ps, '@', "after the signal length")) != 0) return rc;
    if (ps->p >= ps->end || (*ps->p != '0' && *ps->p != '1'))
        return fail(ps, ps->line, "expected the byte order 0 (Motorola) or 1 (Intel) after '@'");
    order_c = (uint32_t)(*ps->p++ - '0');
    if (ps->p >= ps->end || (*ps->p != '+' && *ps->p != '-'))
        return fail(ps, ps->line, "expected '+' (unsigned) or '-' (signed) after the byte order");
    const uint8_t sgn = *ps->p++ == '-';
    if ((rc = expect(ps, '(', "before the factor")) != 0) return rc;
    if ((rc = number(ps, &factor, "the factor")) != 0) return rc;
    if ((rc = expect(ps, ',', "after the factor")) != 0) return rc;
    if ((rc = number(ps, &offset, "the offset")) != 0) return rc;
    if ((rc = expect(ps, ')', "after the offset")) != 0) return rc;
    if ((rc = expect(ps, '[', "before the range")) != 0) return rc;
    if ((rc = number(ps, &lo, "the minimum")) != 0) return rc;
    if ((rc = expect(ps, '|', "between minimum and maximum")) != 0) return rc;
    if ((rc = number(ps, &hi, "the maximum")) != 0) return rc;
    if ((rc = expect(ps, ']', "after the range")) != 0) return rc;
    if ((rc = quoted(ps, &unit, &nu, 0)) != 0) return rc;
    to_eol(ps);   /* the receivers */
    if (ps->cur == -1) return fail(ps, l0, "signal %.*s comes before any BO_ message", (int)nn, name);
    if (ps->cur == -2) return 0;   /* of VECTOR__INDEPENDENT_SIG_MSG */
    if (length < 1 || length > 64) return fail(ps, l0, "signal %.*s: length %u is not 1..64", (int)nn, name, (unsigned)length);
    if (start > 8u * MSID_DBC_MAX_DLC - 1u)
        return fail(ps, l0, "signal %.*s: start bit %u is beyond a 64-byte payload", (int)nn, name, (unsigned)start);
    if (factor == 0) return fail(ps, l0, "signal %.*s: a factor of 0 (no value can be encoded)", (int)nn, name);
    if (ps->mode == COUNT) {
        if (ps->n_sig == UINT32_MAX / 2) return fail(ps, l0, "too many signals");
        ps->n_sig++;
        keep(ps, name, nn);
        keep(ps, unit, nu);
        return 0;
    }
    if (ps->mode == ATTR) return 0;
    msid_dbc *d = ps->d;
    msid_dbc_message *m = &d->messages[ps->cur];
    if (last_byte(start, length, (int)order_c) >= m->dlc)
        return fail(ps, l0, "signal %.*s: its bits (start %u, length %u, %s) leave the %u-byte payload of message %s",
                    (int)nn, name, (unsigned)start, (unsigned)length, order_c ? "Intel" : "Motorola", (unsigned)m->dlc,
                    m->name);
    for (uint32_t k = m->first_signal; k < d->n_signals; ++k)   /* one name in two multiplexed branches is fine */
        if (is(name, nn, d->signals[k].name) &&
            !(role == MSID_DBC_MUXED && d->signals[k].mux == MSID_DBC_MUXED && d->signals[k].mux_value != mux_value))
            return fail(ps, l0, "message %s has two signals named %.*s", m->name, (int)nn, name);
    if (role == MSID_DBC_SWITCH) {
        if (m->mux_signal >= 0)
            return fail(ps, l0,
                        "message %s has a second multiplexer %.*s: extended multiplexing is not supported (msid reads "
                        "simple multiplexing only)",
                        m->name, (int)nn, name);
        m->mux_signal = (int32_t)d->n_signals;
    }
    msid_dbc_signal *s = &d->signals[d->n_signals++];
    m->n_signals++;
    s->name = keep(ps, name, nn);
    s->unit = keep(ps, unit, nu);
    s->start = start;
    s->length = length;
    s->order = (uint8_t)order_c;
    s->is_signed = sgn;
    s->type = MSID_DBC_INT;
    s->mux = role;
    s->mux_value = mux_value;
    s->factor = factor;
    s->offset = offset;
    s->min = lo;
    s->max = hi;
    s->message = (uint32_t)ps->cur;
    s->line = l0;
    return 0;
}

/* A non-negative integral attribute value below 2^32 (a cycle time in ms). */
static int ms_value(parser *ps, uint32_t *v, const char *what)
{
    double x;
    int rc = number(ps, &x, what);
    if (rc) return rc;
    if (!(x >= 0 && x <= 4294967295.0) || x != floor(x))
        return fail(ps, ps->line, "%s %g is not a whole number of milliseconds", what, x);
    *v = (uint32_t)x;
    return 0;
}

/* BA_DEF_ [BU_|BO_|SG_|EV_] "name" ...; : notes whether GenMsgCycleTime is defined (for messages). */
static int st_ba_def(parser *ps, uint32_t l0, const char *kw, size_t kwn)
{
    const char *s;
    size_t n;
    space(ps);
    const size_t k = word(ps, &s, 1);
    const int of_msg = is(s, k, "BO_");
    space(ps);
    if (ps->p < ps->end && *ps->p == '"') {
        int rc = quoted(ps, &s, &n, 1);
        if (rc) return rc;
        if ((k == 0 || of_msg) && is(s, n, CYCLE)) ps->cycle_defined = 1;
    }
    return to_semicolon(ps, l0, kw, kwn);
}

/* BA_DEF_DEF_ "name" value; : the default cycle time. */
static int st_ba_def_def(parser *ps, uint32_t l0, const char *kw, size_t kwn)
{
    const char *s;
    size_t n;
    int rc = quoted(ps, &s, &n, 1);
    if (rc) return rc;
    if (is(s, n, CYCLE)) {
        space(ps);
        if ((rc = ms_value(ps, &ps->cycle_default, "the default GenMsgCycleTime")) != 0) return rc;
    }
    return to_semicolon(ps, l0, kw, kwn);
}

/* BA_ "name" [BU_ node | BO_ id | SG_ id sig | EV_ var] value; : a message's cycle time. */
static int st_ba(parser *ps, uint32_t l0, const char *kw, size_t kwn)
{
    const char *s;
    size_t n;
    int rc = quoted(ps, &s, &n, 1);
    if (rc) return rc;
    if (is(s, n, CYCLE)) {
        const size_t k = word(ps, &s, 1);
        if (is(s, k, "BO_")) {
            uint32_t dbc_id, v = 0;
            space(ps);
            if ((rc = uint_(ps, &dbc_id, "the message identifier")) != 0) return rc;
            space(ps);
            if ((rc = ms_value(ps, &v, "GenMsgCycleTime")) != 0) return rc;
            if (ps->mode == ATTR) {
                msid_dbc_message *m = find_dbc_id(ps, dbc_id);
                if (m && v) m->cycle_ms = v;
            }
        }
    }
    return to_semicolon(ps, l0, kw, kwn);
}

/* SIG_VALTYPE_ id signal [:] 1|2; : float32 or float64 signals. */
static int st_valtype(parser *ps, uint32_t l0, const char *kw, size_t kwn)
{
    uint32_t dbc_id, t;
    const char *s;
    int rc;
    space(ps);
    if ((rc = uint_(ps, &dbc_id, "the message identifier")) != 0) return rc;
    const size_t n = word(ps, &s, 1);
    if (n == 0) return fail(ps, ps->line, "expected the signal name in SIG_VALTYPE_");
    blanks(ps);
    if (ps->p < ps->end && *ps->p == ':') ++ps->p;
    if ((rc = uint_(ps, &t, "the value type")) != 0) return rc;
    if (t > 2) return fail(ps, l0, "SIG_VALTYPE_ %u: value type %u is not 0, 1 (float32) or 2 (float64)", (unsigned)dbc_id, (unsigned)t);
    if ((rc = to_semicolon(ps, l0, kw, kwn)) != 0) return rc;
    if (ps->mode != ATTR) return 0;
    uint32_t id;
    if (dbc_id == 0xC0000000u || !can_id(dbc_id, &id)) return 0;   /* VECTOR__INDEPENDENT_SIG_MSG */
    msid_dbc_message *m = find_dbc_id(ps, dbc_id);
    msid_dbc_signal *sg = NULL;
    if (m) {
        for (uint32_t k = 0; k < m->n_signals; ++k)
            if (is(s, n, ps->d->signals[m->first_signal + k].name)) sg = &ps->d->signals[m->first_signal + k];
    }
    if (!sg)
        return fail(ps, l0, "SIG_VALTYPE_ names signal %.*s of message %u, which the file does not define", (int)n, s,
                    (unsigned)dbc_id);
    if ((t == 1 && sg->length != 32) || (t == 2 && sg->length != 64))
        return fail(ps, l0, "signal %s of message %s is a float%s of %u bits", sg->name, m->name, t == 1 ? "32" : "64",
                    (unsigned)sg->length);
    sg->type = (uint8_t)t;
    return 0;
}

static int skipped(const char *s, size_t n)
{
    for (size_t k = 0; k < sizeof SKIPPED / sizeof SKIPPED[0]; ++k)
        if (is(s, n, SKIPPED[k])) return 1;
    return 0;
}

/* A keyword that starts a statement. */
static int keyword(const char *s, size_t n)
{
    static const char *const KW[] = {"VERSION", "NS_", "BS_", "BU_", "BO_", "SG_", "BA_DEF_", "BA_DEF_DEF_", "BA_",
                                     "SIG_VALTYPE_", "SG_MUL_VAL_"};
    for (size_t k = 0; k < sizeof KW / sizeof KW[0]; ++k)
        if (is(s, n, KW[k])) return 1;
    return skipped(s, n);
}

/* One statement; 1 at the end of the text. */
static int statement(parser *ps)
{
    space(ps);
    if (ps->p >= ps->end) return 1;
    const uint32_t l0 = ps->line;
    const char *kw;
    const size_t n = word(ps, &kw, 0);
    if (n == 0) return fail(ps, l0, "expected a keyword (BO_, SG_, ...), found '%c'", *ps->p);
    if (is(kw, n, "VERSION")) {
        const char *s;
        size_t k;
        return quoted(ps, &s, &k, 0);
    }
    if (is(kw, n, "NS_")) return st_ns(ps);
    if (is(kw, n, "BS_")) {
        to_eol(ps);
        return 0;
    }
    if (is(kw, n, "BU_")) return st_bu(ps);
    if (is(kw, n, "BO_")) return st_bo(ps, l0);
    if (is(kw, n, "SG_")) return st_sg(ps, l0);
    if (is(kw, n, "BA_DEF_")) return st_ba_def(ps, l0, kw, n);
    if (is(kw, n, "BA_DEF_DEF_")) return st_ba_def_def(ps, l0, kw, n);
    if (is(kw, n, "BA_")) return st_ba(ps, l0, kw, n);
    if (is(kw, n, "SIG_VALTYPE_")) return st_valtype(ps, l0, kw, n);
    if (is(kw, n, "SG_MUL_VAL_"))
        return fail(ps, l0, "SG_MUL_VAL_: extended multiplexing is not supported (msid reads simple multiplexing only)");
    if (skipped(kw, n)) return to_semicolon(ps, l0, kw, n);
    return fail(ps, l0, "unknown keyword '%.*s'", (int)(n > 40 ? 40 : n), kw);
}

static int run(parser *ps, const char *text, size_t len, int mode)
{
    ps->p = text;
    ps->end = text + len;
    ps->line = 1;
    ps->mode = mode;
    ps->cur = -1;
    ps->cycle_defined = 0;
    ps->cycle_default = 0;
    for (;;) {
        const int rc = statement(ps);
        if (rc < 0) return rc;
        if (rc == 1) return 0;
    }
}

/* ---- the tables ---- */

static size_t up8(size_t n) { return (n + 7u) & ~(size_t)7u; }

/* The one layout: messages, signals, the two indices, the names. base NULL: the size only. */
static size_t layout(msid_dbc *d, uint32_t n_msg, uint32_t n_sig, size_t n_str, unsigned char *base)
{
    size_t off = 0;
    const size_t o_msg = off;
    off += up8(sizeof(msid_dbc_message) * (size_t)n_msg);
    const size_t o_sig = off;
    off += up8(sizeof(msid_dbc_signal) * (size_t)n_sig);
    const size_t o_id = off;
    off += up8(sizeof(uint32_t) * (size_t)n_msg);
    const size_t o_nm = off;
    off += up8(sizeof(uint32_t) * (size_t)n_msg);
    const size_t o_str = off;
    off += up8(n_str + 1u);
    if (base) {
        d->messages = (msid_dbc_message *)(void *)(base + o_msg);
        d->signals = (msid_dbc_signal *)(void *)(base + o_sig);
        d->by_id = (uint32_t *)(void *)(base + o_id);
        d->by_name = (uint32_t *)(void *)(base + o_nm);
        ((char *)base)[o_str] = 0;
        return o_str;
    }
    return off;
}

/* Heapsort of message indices (no allocation, no recursion): by id or by name. */
static int less(const msid_dbc *d, uint32_t a, uint32_t b, int by_name)
{
    if (by_name) return strcmp(d->messages[a].name, d->messages[b].name) < 0;
    return d->messages[a].id < d->messages[b].id;
}

static void sift(const msid_dbc *d, uint32_t *v, size_t i, size_t n, int by_name)
{
    for (;;) {
        size_t c = 2u * i + 1u;
        if (c >= n) return;
        if (c + 1u < n && less(d, v[c], v[c + 1u], by_name)) ++c;
        if (!less(d, v[i], v[c], by_name)) return;
        const uint32_t t = v[i];
        v[i] = v[c];
        v[c] = t;
        i = c;
    }
}

static void sort_index(const msid_dbc *d, uint32_t *v, size_t n, int by_name)
{
    for (size_t i = 0; i < n; ++i) v[i] = (uint32_t)i;
    if (n < 2u) return;
    for (size_t i = n / 2u; i-- > 0u;) sift(d, v, i, n, by_name);
    for (size_t e = n - 1u; e > 0u; --e) {
        const uint32_t t = v[0];
        v[0] = v[e];
        v[e] = t;
        sift(d, v, 0, e, by_name);
    }
}

/* Two messages of one identifier or one name: the later one's line. */
static int check_unique(parser *ps)
{
    const msid_dbc *d = ps->d;
    for (uint32_t k = 1; k < d->n_messages; ++k) {
        const msid_dbc_message *a = &d->messages[d->by_id[k - 1]], *b = &d->messages[d->by_id[k]];
        if (a->id == b->id) {
            const msid_dbc_message *l = a->line > b->line ? a : b, *f = a->line > b->line ? b : a;
            return fail(ps, l->line, "message %s has the identifier of message %s (line %u)", l->name, f->name,
                        (unsigned)f->line);
        }
        a = &d->messages[d->by_name[k - 1]];
        b = &d->messages[d->by_name[k]];
        if (!strcmp(a->name, b->name))
            return fail(ps, a->line > b->line ? a->line : b->line, "two messages are named %s (lines %u and %u)",
                        a->name, (unsigned)(a->line < b->line ? a->line : b->line),
                        (unsigned)(a->line > b->line ? a->line : b->line));
    }
    /* a multiplexed signal needs its message's switch; a bare 'm' is a plain signal without one */
    for (uint32_t k = 0; k < d->n_signals; ++k) {
        msid_dbc_signal *s = &ps->d->signals[k];
        const int has_switch = d->messages[s->message].mux_signal >= 0;
        if (s->mux == MSID_DBC_MUXED && s->mux_value == BARE_M) {
            if (has_switch) return fail(ps, s->line, "signal %s: multiplexer indicator 'm' without a value", s->name);
            s->mux = MSID_DBC_PLAIN;
            s->mux_value = 0;
        } else if (s->mux == MSID_DBC_MUXED && !has_switch) {
            return fail(ps, s->line, "signal %s is multiplexed (m%u) but message %s has no multiplexer (M)", s->name,
                        (unsigned)s->mux_value, d->messages[s->message].name);
        }
    }
    return 0;
}

size_t msid_dbc_mem_size(const char *text, size_t len)
{
    if (!text) return 0;
    parser ps;
    memset(&ps, 0, sizeof ps);
    msid_dbc tmp;
    memset(&tmp, 0, sizeof tmp);
    ps.d = &tmp;
    if (run(&ps, text, len, COUNT)) return 0;
    return layout(&tmp, ps.n_msg, ps.n_sig, ps.n_str, NULL);
}

static int refuse(msid_dbc *d, int rc, const parser *ps)
{
    memcpy(d->err, ps->err, sizeof d->err);
    d->err[sizeof d->err - 1] = 0;
    d->err_line = ps->err_line;
    d->n_messages = d->n_signals = 0;
    return rc;
}

int msid_dbc_init(msid_dbc *d, const char *text, size_t len, void *mem, size_t mem_len)
{
    if (!d) return -MSID_DAQ_E_ARG;
    memset(d, 0, sizeof *d);
    if (!text) {
        snprintf(d->err, sizeof d->err, "no DBC text");
        return -MSID_DAQ_E_ARG;
    }
    parser ps;
    memset(&ps, 0, sizeof ps);
    ps.d = d;
    int rc = run(&ps, text, len, COUNT);
    if (rc) return refuse(d, rc, &ps);
    const size_t need = layout(d, ps.n_msg, ps.n_sig, ps.n_str, NULL);
    if (!mem || mem_len < need || ((uintptr_t)mem & 7u)) {
        snprintf(d->err, sizeof d->err, !mem || mem_len < need ? "%zu bytes of memory given, %zu needed"
                                                               : "memory not aligned to 8 bytes (%zu bytes given, %zu needed)",
                 mem ? mem_len : (size_t)0, need);
        return -MSID_DAQ_E_ARG;
    }
    ps.str = (char *)mem + layout(d, ps.n_msg, ps.n_sig, ps.n_str, (unsigned char *)mem);
    if ((rc = run(&ps, text, len, PLACE)) != 0) return refuse(d, rc, &ps);
    sort_index(d, d->by_id, d->n_messages, 0);
    sort_index(d, d->by_name, d->n_messages, 1);
    if ((rc = check_unique(&ps)) != 0) return refuse(d, rc, &ps);
    if ((rc = run(&ps, text, len, ATTR)) != 0) return refuse(d, rc, &ps);
    /* as cantools: a cycle time only where a BA_DEF_ defines GenMsgCycleTime; 0 means none */
    for (uint32_t k = 0; k < d->n_messages; ++k) {
        msid_dbc_message *m = &d->messages[k];
        if (!ps.cycle_defined) m->cycle_ms = 0;
        else if (m->cycle_ms == 0) m->cycle_ms = ps.cycle_default;
    }
    return 0;
}

/* ---- lookup ---- */

const msid_dbc_message *msid_dbc_message_by_id(const msid_dbc *d, uint32_t id)
{
    if (!d || !d->n_messages) return NULL;
    size_t lo = 0, hi = d->n_messages;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2u;
        const uint32_t v = d->messages[d->by_id[mid]].id;
        if (v == id) return &d->messages[d->by_id[mid]];
        if (v < id) lo = mid + 1u;
        else hi = mid;
    }
    return NULL;
}

const msid_dbc_message *msid_dbc_message_by_name(const msid_dbc *d, const char *name)
{
    if (!d || !name || !d->n_messages) return NULL;
    size_t lo = 0, hi = d->n_messages;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2u;
        const int c = strcmp(d->messages[d->by_name[mid]].name, name);
        if (c == 0) return &d->messages[d->by_name[mid]];
        if (c < 0) lo = mid + 1u;
        else hi = mid;
    }
    return NULL;
}

const msid_dbc_signal *msid_dbc_signal_by_name(const msid_dbc *d, const msid_dbc_message *m, const char *name)
{
    if (!d || !m || !name) return NULL;
    for (uint32_t k = 0; k < m->n_signals; ++k)
        if (!strcmp(d->signals[m->first_signal + k].name, name)) return &d->signals[m->first_signal + k];
    return NULL;
}

/* ---- the codec ---- */

uint32_t msid_dbc_signal_bytes(const msid_dbc_signal *s) { return last_byte(s->start, s->length, s->order) + 1u; }

static uint64_t low_mask(uint32_t n) { return n >= 64u ? ~(uint64_t)0 : (((uint64_t)1 << n) - 1u); }

int msid_dbc_get_raw(const msid_dbc_signal *s, const uint8_t *data, size_t len, uint64_t *raw)
{
    if (msid_dbc_signal_bytes(s) > len) return -MSID_DAQ_E_SHORT;
    uint64_t v = 0;
    uint32_t got = 0;
    if (s->order == MSID_DBC_INTEL) {   /* bit b is bit b%8 of byte b/8; the first is the least significant */
        uint32_t b = s->start;
        while (got < s->length) {
            const uint32_t off = b % 8u, take = s->length - got < 8u - off ? s->length - got : 8u - off;
            v |= (uint64_t)((data[b / 8u] >> off) & low_mask(take)) << got;
            got += take;
            b += take;
        }
    } else {   /* MSB-first positions from the start bit's: the first is the most significant */
        uint32_t p = msb_pos(s->start);
        while (got < s->length) {
            const uint32_t off = p % 8u, take = s->length - got < 8u - off ? s->length - got : 8u - off;
            const uint64_t bits = (uint64_t)(data[p / 8u] >> (8u - off - take)) & low_mask(take);
            v = (v << take) | bits;
            got += take;
            p += take;
        }
    }
    *raw = v;
    return 0;
}

int msid_dbc_set_raw(const msid_dbc_signal *s, uint64_t raw, uint8_t *data, size_t len)
{
    if (msid_dbc_signal_bytes(s) > len) return -MSID_DAQ_E_SHORT;
    if (raw & ~low_mask(s->length)) return -MSID_DAQ_E_RANGE;
    uint32_t put = 0;
    if (s->order == MSID_DBC_INTEL) {
        uint32_t b = s->start;
        while (put < s->length) {
            const uint32_t off = b % 8u, take = s->length - put < 8u - off ? s->length - put : 8u - off;
            const unsigned m = (unsigned)(low_mask(take) << off);
            const unsigned bits = (unsigned)(((raw >> put) & low_mask(take)) << off);
            data[b / 8u] = (uint8_t)((data[b / 8u] & ~m) | bits);
            put += take;
            b += take;
        }
    } else {
        uint32_t p = msb_pos(s->start);
        while (put < s->length) {
            const uint32_t off = p % 8u, take = s->length - put < 8u - off ? s->length - put : 8u - off;
            const uint32_t sh = 8u - off - take;
            const unsigned m = (unsigned)(low_mask(take) << sh);
            const unsigned bits = (unsigned)(((raw >> (s->length - put - take)) & low_mask(take)) << sh);
            data[p / 8u] = (uint8_t)((data[p / 8u] & ~m) | bits);
            put += take;
            p += take;
        }
    }
    return 0;
}

/* The raw bits as the number they stand for. */
static double raw_value(const msid_dbc_signal *s, uint64_t raw)
{
    if (s->type == MSID_DBC_FLOAT32) {
        const uint32_t u = (uint32_t)raw;
        float f;
        memcpy(&f, &u, sizeof f);
        return (double)f;
    }
    if (s->type == MSID_DBC_FLOAT64) {
        double x;
        memcpy(&x, &raw, sizeof x);
        return x;
    }
    if (s->is_signed && (raw >> (s->length - 1u)) & 1u) {
        const uint64_t ext = raw | ~low_mask(s->length);   /* two's complement, sign-extended */
        return -(double)(~ext + 1u);                      /* -2^63 included: ~ext + 1 = 2^63 */
    }
    return (double)raw;
}

int msid_dbc_decode(const msid_dbc_signal *s, const uint8_t *data, size_t len, double *phys)
{
    uint64_t raw;
    const int rc = msid_dbc_get_raw(s, data, len, &raw);
    if (rc) return rc;
    const double v = raw_value(s, raw);
    *phys = v * s->factor + s->offset;
    return 0;
}

/* The raw bits of a physical value, or -MSID_DAQ_E_RANGE. */
static int raw_of(const msid_dbc_signal *s, double phys, uint64_t *raw)
{
    if (!isfinite(phys)) return -MSID_DAQ_E_RANGE;
    if (s->min < s->max) {
        const double tol = fabs(s->factor) * 1e-6;
        if (phys < s->min - tol || phys > s->max + tol) return -MSID_DAQ_E_RANGE;
    }
    const double r = (phys - s->offset) / s->factor;
    if (!isfinite(r)) return -MSID_DAQ_E_RANGE;
    if (s->type == MSID_DBC_FLOAT32) {
        if (fabs(r) >= 0x1.ffffffp+127) return -MSID_DAQ_E_RANGE;   /* rounds to infinity as a float32 */
        const float f = (float)r;
        uint32_t u;
        memcpy(&u, &f, sizeof u);
        *raw = u;
        return 0;
    }
    if (s->type == MSID_DBC_FLOAT64) {
        memcpy(raw, &r, sizeof r);
        return 0;
    }
    const double q = nearbyint(r);   /* ties to even (the default rounding mode), as Python's round() */
    if (s->is_signed) {
        const double h = ldexp(1.0, (int)s->length - 1);
        if (!(q >= -h && q < h)) return -MSID_DAQ_E_RANGE;
        *raw = q < 0 ? (~(uint64_t)(-q) + 1u) & low_mask(s->length) : (uint64_t)q;
        return 0;
    }
    if (!(q >= 0 && q < ldexp(1.0, (int)s->length))) return -MSID_DAQ_E_RANGE;
    *raw = (uint64_t)q;
    return 0;
}

int msid_dbc_encode(const msid_dbc_signal *s, double phys, uint8_t *data, size_t len)
{
    if (msid_dbc_signal_bytes(s) > len) return -MSID_DAQ_E_SHORT;
    uint64_t raw;
    const int rc = raw_of(s, phys, &raw);
    if (rc) return rc;
    return msid_dbc_set_raw(s, raw, data, len);
}

int msid_dbc_present(const msid_dbc *d, const msid_dbc_signal *s, const uint8_t *data, size_t len)
{
    if (s->mux != MSID_DBC_MUXED) return 1;
    const int32_t k = d->messages[s->message].mux_signal;
    if (k < 0) return 0;
    uint64_t raw;
    const int rc = msid_dbc_get_raw(&d->signals[k], data, len, &raw);
    if (rc) return rc;
    return raw == s->mux_value;
}
