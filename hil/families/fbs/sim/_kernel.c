/* The emulator's compiled span kernel: many scans of a running FUN86 PLC (temperature modules, FUN86 instances,
 * thermal plant) between two requests, with exactly the arithmetic of the Python models, in the same order.
 *
 * hil/emulator/kernel.py decides when it applies, packs the models' state into flat float64 records, calls run()
 * and unpacks the result; the Python models stay the reference (tests/test_kernel.py compares the two bit for bit).
 * Every line below mirrors a line of models/temperature.py (_measure_plain), models/fun86.py (_scan_instance,
 * _replay, control, next_event) or models/plant.py (_Waved, ThermalPlant.scan): change them together.
 *
 * Floating point: no contraction into FMA (setup.py passes -ffp-contract=off), libm's exp like math.exp, rint()
 * for Python's round() (half to even), floor/ceil for math.floor/ceil.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* -- record layouts (exported to Python as FIELDS, so both sides index by name) ------------------------------- */
#define ENGINE(X) X(now) X(target) X(scan_time) X(scans) X(version) X(fahrenheit) X(fast) X(averaging)
#define MODULE(X) X(first) X(points) X(step) X(next) X(mux) X(has_sensor) X(low) X(high)
#define TPOINT(X) X(installed) X(broken) X(source) X(c0) X(c1) X(c2) X(c3) X(plant) X(upper) X(samples) \
    X(s0) X(s1) X(s2) X(s3) X(s4) X(s5) X(s6) X(s7) X(reading) X(written) X(breakbit)
#define PLANT(X) X(ambient) X(gain) X(tau) X(noise) X(seed_lo) X(seed_hi) X(point) X(t0) X(temp0) X(wave) X(u) \
    X(started) X(period) X(on) X(u_on) X(u_off) X(wst) X(drive) X(ref) X(bit)
#define INST(X) X(sn) X(zn) X(first) X(interval) X(pwm) X(started) X(next_pid) X(heating) X(limit) \
    X(loop_percent) X(loop_seconds) X(md) X(normal0) X(normal1) X(warn0) X(warn1) X(alm)
#define PID(X) X(point) X(enabled) X(kc) X(ki) X(td) X(sv) X(os) X(integral) X(has_prev) \
    X(pv_prev) X(prealarm) X(has_loop) X(loop_since) X(out) X(y) X(has_wave) X(w_started) X(w_pwm) X(w_on) \
    X(w_yon) X(w_yoff)

#define E_ITEM(name) E_##name,
#define M_ITEM(name) M_##name,
#define T_ITEM(name) T_##name,
#define L_ITEM(name) L_##name,
#define I_ITEM(name) I_##name,
#define P_ITEM(name) P_##name,
enum { ENGINE(E_ITEM) E_SIZE };
enum { MODULE(M_ITEM) M_SIZE };
enum { TPOINT(T_ITEM) T_SIZE };
enum { PLANT(L_ITEM) L_SIZE };
enum { INST(I_ITEM) I_SIZE };
enum { PID(P_ITEM) P_SIZE };

#define SOURCE_FIXED 0
#define SOURCE_RAMP 1
#define SOURCE_PLANT 2
#define BREAK_VALUE 28767
#define OUTPUT_FULL 16383
#define PREALARM_SCANS 10
#define NORMALS 65536

typedef struct {
    double *eng, *mods, *tps, *plant, *insts, *pids;
    const double *normals;
    Py_ssize_t n_mods, n_tps, n_plant, n_insts;
    /* this scan's readings per temperature point (FUN86 replays them): times and signed readings */
    double **log_at;
    int **log_pv;
    int *log_n, *log_cap;
    /* optional, for tests: per scan (now, then per instance normal0, normal1, warn0, warn1, ALM, Yn… as a bit mask,
       sum of OR) — what a request at that scan would have seen */
    double *trace;
    Py_ssize_t trace_cap, traced;
} Kernel;

#define TRACE_PER_INSTANCE 7

static double grid(double x, double st) { return ceil(x / st - 1e-6) * st; }

static double py_mod(double a, double b) {  /* Python's float % for b > 0 */
    double m = fmod(a, b);
    if (m) {
        if ((b < 0) != (m < 0)) m += b;
    } else {
        m = copysign(0.0, b);
    }
    return m;
}

static int signed16(long v) { v &= 0xFFFF; return (int)(v & 0x8000 ? v - 0x10000 : v); }

/* -- the plant (plant.py: _Waved.temperature / measured, without the memo, which only skips repeated work) ----- */
static double plant_temperature(const double *p, double t) {
    double temp = p[L_temp0], a = p[L_t0];
    if (t <= a) return temp;
    double tau = p[L_tau];
    if (p[L_wave] == 0) {
        double target = p[L_ambient] + p[L_gain] * p[L_u];
        return target + (temp - target) * exp(-(t - a) / tau);
    }
    double started = p[L_started], period = p[L_period], on = p[L_on], st = p[L_wst];
    double t_on = p[L_ambient] + p[L_gain] * p[L_u_on], t_off = p[L_ambient] + p[L_gain] * p[L_u_off];
    double k = floor((a - started) / period) - 1;
    double start = grid(started + k * period, st);
    double off = grid(started + k * period + on, st);
    double nxt = grid(started + (k + 1) * period, st);
    while (start < t) {
        double lo = start > a ? start : a, hi = off < t ? off : t;
        if (hi > lo) temp = t_on + (temp - t_on) * exp(-(hi - lo) / tau);
        lo = off > a ? off : a;
        hi = nxt < t ? nxt : t;
        if (hi > lo) temp = t_off + (temp - t_off) * exp(-(hi - lo) / tau);
        k += 1;
        start = nxt;
        if (start >= t) break;
        off = grid(started + k * period + on, st);
        nxt = grid(started + (k + 1) * period, st);
    }
    return temp;
}

/* plant.py _noise_index: splitmix64 of (microseconds, point, seed); the seed (any Python int) arrives as its two
 * 32-bit halves modulo 2^64, which is all that Python's `seed * K & MASK` keeps of it */
static unsigned noise_index(const double *p, double t) {
    uint64_t micros = (uint64_t)(int64_t)rint(t * 1000000.0);
    uint64_t seed = (uint64_t)p[L_seed_hi] << 32 | (uint64_t)p[L_seed_lo];
    uint64_t x = micros * 0x9E3779B97F4A7C15ULL + (uint64_t)(int64_t)p[L_point] * 0xBF58476D1CE4E5B9ULL
                 + seed * 0x94D049BB133111EBULL;
    x ^= x >> 30;
    x *= 0xBF58476D1CE4E5B9ULL;
    x ^= x >> 27;
    x *= 0x94D049BB133111EBULL;
    x ^= x >> 31;
    return (unsigned)(x & 0xFFFF);
}

static double plant_measured(const Kernel *k, const double *p, double t) {
    double value = plant_temperature(p, t);
    if (p[L_noise]) value += k->normals[noise_index(p, t)] * p[L_noise];
    return value;
}

static double source_at(const Kernel *k, const double *tp, double t) {
    switch ((int)tp[T_source]) {
    case SOURCE_FIXED: return tp[T_c0];
    case SOURCE_RAMP: {
        double v = tp[T_c0] + tp[T_c1] * t;
        v = v > tp[T_c2] ? v : tp[T_c2];  /* max(start + per_s·t, low) */
        return v < tp[T_c3] ? v : tp[T_c3];
    }
    default: return plant_measured(k, k->plant + (Py_ssize_t)tp[T_plant] * L_SIZE, t);
    }
}

/* -- temperature modules (temperature.py: _measure_plain) ----------------------------------------------------- */
static int log_reading(Kernel *k, int point, double at, int pv) {
    if (k->log_n[point] == k->log_cap[point]) {
        int cap = k->log_cap[point] ? 2 * k->log_cap[point] : 16;
        double *ats = realloc(k->log_at[point], cap * sizeof(double));
        if (!ats) return -1;
        k->log_at[point] = ats;
        int *pvs = realloc(k->log_pv[point], cap * sizeof(int));
        if (!pvs) return -1;
        k->log_pv[point] = pvs;
        k->log_cap[point] = cap;
    }
    k->log_at[point][k->log_n[point]] = at;
    k->log_pv[point][k->log_n[point]] = pv;
    k->log_n[point]++;
    return 0;
}

static int measure_module(Kernel *k, double *m, double now) {
    double limit = now + 1e-9, step = m[M_step];
    double at = m[M_next];
    int mux = (int)m[M_mux], points = (int)m[M_points], first = (int)m[M_first];
    int fahrenheit = k->eng[E_fahrenheit] != 0, fast = k->eng[E_fast] != 0;
    while (at <= limit) {
        int point = first + mux;
        double *tp = k->tps + (Py_ssize_t)point * T_SIZE;
        long reading;
        if (tp[T_installed] && !tp[T_broken]) {
            double celsius = source_at(k, tp, at);
            if (m[M_has_sensor]) {
                celsius = celsius > m[M_low] ? celsius : m[M_low];
                celsius = celsius < m[M_high] ? celsius : m[M_high];
            }
            double value = fahrenheit ? celsius * 9 / 5 + 32 : celsius;
            /* the last `averaging` values, oldest first (temperature.py: a deque with maxlen; mean_of) */
            int n = (int)tp[T_samples], averaging = (int)k->eng[E_averaging];
            double *samples = tp + T_s0;
            if (n == averaging) {
                memmove(samples, samples + 1, (n - 1) * sizeof(double));
                n--;
            }
            samples[n++] = value;
            tp[T_samples] = n;
            double mean = value;
            if (n > 1) {
                double total = 0.0;
                for (int i = 0; i < n; i++) total += samples[i];
                mean = total / n;
            }
            reading = fast ? (long)rint(mean) * 10 : (long)rint(mean * 10);
            tp[T_breakbit] = 0;
        } else {
            tp[T_samples] = 0;
            if (tp[T_broken] && tp[T_installed]) {
                reading = BREAK_VALUE;
                tp[T_breakbit] = 1;
            } else {
                reading = 0;
                tp[T_breakbit] = 0;
            }
        }
        tp[T_reading] = (double)(reading & 0xFFFF);
        tp[T_written] = 1;
        if (log_reading(k, point, at, signed16(reading)) < 0) return -1;
        mux = (mux + 1) % points;
        at += step;
    }
    m[M_next] = at;
    m[M_mux] = mux;
    return 0;
}

/* -- FUN86 (fun86.py) ------------------------------------------------------------------------------------------ */
static int in_band(int pv, int sv, int os) { return sv - os <= pv && pv <= sv + os; }

/* PV: FUN86 reads the temperature readings (kernel.py admits no other source), so point Sn + b's reading */
static int pv_of(const Kernel *k, const double *pp) {
    return signed16((long)k->tps[(Py_ssize_t)pp[P_point] * T_SIZE + T_reading]);
}

static long control(double *pp, const double *in, int pv, double ts) {
    int heating = in[I_heating] != 0;
    long kc = (long)pp[P_kc], ki = (long)pp[P_ki], td = (long)pp[P_td];
    int sv = (int)pp[P_sv];
    long error = heating ? (sv - pv) : (pv - sv);
    long proportional = kc * error;
    double slope = pp[P_has_prev] ? (pv - pp[P_pv_prev]) / ts : 0.0;
    double derivative = (double)(-kc) * ((double)td / 100 * 60) * slope * (heating ? 1 : -1);
    if (ki && (in[I_md] == 1 || labs(proportional) < OUTPUT_FULL)) {
        double integral = pp[P_integral] + (double)kc * ((double)ki / 100 / 60) * ts * (double)error;
        integral = integral > -OUTPUT_FULL ? integral : -OUTPUT_FULL;
        pp[P_integral] = integral < OUTPUT_FULL ? integral : OUTPUT_FULL;
    }
    if (!ki) pp[P_integral] = 0.0;
    pp[P_has_prev] = 1;
    pp[P_pv_prev] = pv;
    double total = rint((double)proportional + pp[P_integral] + derivative);
    total = total > 0 ? total : 0;
    return (long)(total < OUTPUT_FULL ? total : OUTPUT_FULL);
}

static void replay(const Kernel *k, double *pp, int point, double now, double st, int high, int sv, int os,
                   long limit) {
    for (int i = 0; i < k->log_n[point]; i++) {
        double landed = grid(k->log_at[point][i], st);
        if (landed >= now - st / 2) continue;  /* read at this very scan */
        int pv = k->log_pv[point][i];
        pp[P_prealarm] = pv >= limit ? pp[P_prealarm] + 1 : 0;
        if (high && !in_band(pv, sv, os)) {
            if (!pp[P_has_loop]) { pp[P_has_loop] = 1; pp[P_loop_since] = landed; }
        } else {
            pp[P_has_loop] = 0;
        }
    }
}

static void scan_instance(Kernel *k, double *in, double now, double st) {
    int zn = (int)in[I_zn];
    long limit = (long)in[I_limit], loop_seconds = (long)in[I_loop_seconds];
    int pid_due = now >= in[I_next_pid] - 1e-9;
    if (pid_due) {
        while (in[I_next_pid] <= now + 1e-9) in[I_next_pid] += in[I_interval];
    }
    double pwm = in[I_pwm], started = in[I_started];
    double phase = py_mod(now - started, pwm);
    long high_at = (long)in[I_loop_percent] * OUTPUT_FULL;
    long normal[2] = {0, 0}, warning[2] = {0, 0};
    int out_of_band = 0, warn = 0;
    for (int b = 0; b < zn; b++) {
        double *pp = k->pids + ((Py_ssize_t)in[I_first] + b) * P_SIZE;
        int pv = pv_of(k, pp), sv = (int)pp[P_sv], os = (int)pp[P_os];
        int enabled = pp[P_enabled] != 0;
        if (enabled && k->log_n[(int)pp[P_point]] > 0)
            replay(k, pp, (int)pp[P_point], now, st, (long)pp[P_out] * 100 >= high_at, sv, os, limit);
        if (pid_due) {
            if (enabled) {
                pp[P_out] = (double)control(pp, in, pv, in[I_interval]);
            } else {
                pp[P_out] = 0;
                pp[P_integral] = 0.0;
                pp[P_has_prev] = 0;
            }
        }
        long value = (long)pp[P_out];
        double on_time = (double)value / OUTPUT_FULL * pwm;
        int y_on = enabled, y_off = 0;
        pp[P_y] = (phase < on_time ? y_on : y_off) ? 1 : 0;
        if (!pp[P_has_wave] || pp[P_w_started] != started || pp[P_w_pwm] != pwm || pp[P_w_on] != on_time
            || pp[P_w_yon] != y_on || pp[P_w_yoff] != y_off) {
            pp[P_has_wave] = 1;
            pp[P_w_started] = started;
            pp[P_w_pwm] = pwm;
            pp[P_w_on] = on_time;
            pp[P_w_yon] = y_on;
            pp[P_w_yoff] = y_off;
            k->eng[E_version] += 1;
        }
        int word = b / 16, bit = b % 16;
        if (!enabled) {
            pp[P_prealarm] = 0;
            pp[P_has_loop] = 0;
            continue;
        }
        int normal_now = in_band(pv, sv, os);
        if (normal_now) normal[word] |= 1L << bit;
        else out_of_band = 1;
        pp[P_prealarm] = pv >= limit ? pp[P_prealarm] + 1 : 0;
        if (value * 100 >= high_at && !normal_now) {
            if (!pp[P_has_loop]) { pp[P_has_loop] = 1; pp[P_loop_since] = now; }
        } else {
            pp[P_has_loop] = 0;
        }
        int loop_open = pp[P_has_loop] && now - pp[P_loop_since] >= loop_seconds;
        if (pp[P_prealarm] >= PREALARM_SCANS || loop_open) {
            warning[word] |= 1L << bit;
            warn = 1;
        }
    }
    in[I_normal0] = normal[0] & 0xFFFF;
    in[I_normal1] = normal[1] & 0xFFFF;
    in[I_warn0] = warning[0] & 0xFFFF;
    in[I_warn1] = warning[1] & 0xFFFF;
    in[I_alm] = (out_of_band || warn) ? 1 : 0;
}

/* temperature.py readings_upper ≥ R4008 for the instance's enabled points (fun86.py _prealarm_possible) */
static int prealarm_possible(const Kernel *k, const double *in) {
    double top = -INFINITY;
    int any = 0, unknown = 0;
    for (int b = 0; b < (int)in[I_zn]; b++) {
        const double *pp = k->pids + ((Py_ssize_t)in[I_first] + b) * P_SIZE;
        if (!pp[P_enabled]) continue;
        any = 1;
        const double *tp = k->tps + (Py_ssize_t)pp[P_point] * T_SIZE;
        double value = tp[T_upper];
        for (int i = 0; i < (int)tp[T_samples]; i++)
            if (tp[T_s0 + i] > value) value = tp[T_s0 + i];
        if (value > top) top = value;
        if (tp[T_broken] || !tp[T_installed]) unknown = 1;
    }
    if (!any) return 0;
    if (unknown || isinf(top)) return 1;
    double upper = k->eng[E_fast] ? (ceil(top) + 1) * 10 : ceil(top * 10) + 1;
    return upper >= in[I_limit];
}

static double next_measurement(const Kernel *k) {
    double due = INFINITY;
    for (Py_ssize_t i = 0; i < k->n_mods; i++)
        if (k->mods[i * M_SIZE + M_next] < due) due = k->mods[i * M_SIZE + M_next];
    return due;
}

static double fun86_next_event(const Kernel *k, double now) {
    double due = INFINITY;
    int measurements = 0;
    for (Py_ssize_t i = 0; i < k->n_insts; i++) {
        const double *in = k->insts + i * I_SIZE;
        double loop_seconds = in[I_loop_seconds];
        for (int b = 0; b < (int)in[I_zn]; b++) {
            const double *pp = k->pids + ((Py_ssize_t)in[I_first] + b) * P_SIZE;
            if (0 < pp[P_prealarm] && pp[P_prealarm] < 4 * PREALARM_SCANS) return now;
            if (pp[P_has_loop] && pp[P_loop_since] + loop_seconds > now + 1e-9 && pp[P_loop_since] + loop_seconds < due)
                due = pp[P_loop_since] + loop_seconds;
        }
        if (in[I_next_pid] < due) due = in[I_next_pid];
        if (!measurements) measurements = prealarm_possible(k, in);
    }
    if (due < INFINITY && measurements) {
        double m = next_measurement(k);
        if (m < due) due = m;
    }
    if (isinf(due)) return due;
    double st = k->eng[E_scan_time], landed = grid(due, st);
    return landed > now ? landed : now;
}

/* -- the plant's scan (plant.py ThermalPlant.scan, waved) -------------------------------------------------------- */
static void plant_scan(Kernel *k, double now) {
    double st = k->eng[E_scan_time];
    for (Py_ssize_t i = 0; i < k->n_plant; i++) {
        double *p = k->plant + i * L_SIZE;
        double wave = 0, u = p[L_bit], started = 0, period = 0, on = 0, u_on = 0, u_off = 0;
        if (p[L_drive]) {
            const double *pp = k->pids + (Py_ssize_t)p[L_ref] * P_SIZE;
            started = pp[P_w_started];
            period = pp[P_w_pwm];
            on = pp[P_w_on];
            u_on = pp[P_w_yon] ? 1 : 0;
            u_off = pp[P_w_yoff] ? 1 : 0;
            if (u_on == u_off || on <= 0) u = u_off;
            else if (on >= period) u = u_on;
            else wave = 1;
        }
        int same = wave == 0 ? (p[L_wave] == 0 && p[L_u] == u)
                             : (p[L_wave] == 1 && p[L_started] == started && p[L_period] == period && p[L_on] == on
                                && p[L_u_on] == u_on && p[L_u_off] == u_off && p[L_wst] == st);
        if (same) continue;
        if (now > p[L_t0]) {
            p[L_temp0] = plant_temperature(p, now);
            p[L_t0] = now;
        }
        p[L_wave] = wave;
        if (wave == 0) {
            p[L_u] = u;
        } else {
            p[L_started] = started;
            p[L_period] = period;
            p[L_on] = on;
            p[L_u_on] = u_on;
            p[L_u_off] = u_off;
            p[L_wst] = st;
        }
    }
}

/* -- the engine (core.py Emulator.advance_to, after its first scan) --------------------------------------------- */
static int scan(Kernel *k, double now) {
    for (Py_ssize_t t = 0; t < k->n_tps; t++) k->log_n[t] = 0;
    for (Py_ssize_t i = 0; i < k->n_mods; i++) {
        double *m = k->mods + i * M_SIZE;
        if (m[M_next] <= now + 1e-9 && measure_module(k, m, now) < 0) return -1;
    }
    for (Py_ssize_t i = 0; i < k->n_insts; i++) scan_instance(k, k->insts + i * I_SIZE, now, k->eng[E_scan_time]);
    plant_scan(k, now);
    return 0;
}

static int run_span(Kernel *k) {
    double *eng = k->eng;
    double st = eng[E_scan_time], target = eng[E_target];
    while (eng[E_now] + st <= target + 1e-9) {
        double due = fun86_next_event(k, eng[E_now]);
        double landing = due > eng[E_now] + st ? due : eng[E_now] + st;
        landing = landing < target ? landing : target;
        eng[E_now] = landing - st;
        eng[E_now] += st;
        eng[E_scans] += 1;
        if (scan(k, eng[E_now]) < 0) return -1;
        Py_ssize_t size = 1 + TRACE_PER_INSTANCE * k->n_insts;
        if (k->trace && (k->traced + 1) * size <= k->trace_cap) {
            double *r = k->trace + k->traced++ * size;
            *r++ = eng[E_now];
            for (Py_ssize_t i = 0; i < k->n_insts; i++) {
                const double *in = k->insts + i * I_SIZE;
                double y = 0, or_sum = 0;
                for (int b = 0; b < (int)in[I_zn]; b++) {
                    const double *pp = k->pids + ((Py_ssize_t)in[I_first] + b) * P_SIZE;
                    if (pp[P_y]) y += ldexp(1.0, b);
                    or_sum += pp[P_out];
                }
                *r++ = in[I_normal0]; *r++ = in[I_normal1]; *r++ = in[I_warn0]; *r++ = in[I_warn1];
                *r++ = in[I_alm]; *r++ = y; *r++ = or_sum;
            }
        }
    }
    return 0;
}

static int get_buffer(PyObject *obj, Py_buffer *view, Py_ssize_t record, const char *what, Py_ssize_t *count) {
    if (PyObject_GetBuffer(obj, view, PyBUF_WRITABLE | PyBUF_FORMAT | PyBUF_C_CONTIGUOUS) < 0) return -1;
    if (!view->format || strcmp(view->format, "d") != 0 || view->len % (record * (Py_ssize_t)sizeof(double))) {
        PyErr_Format(PyExc_ValueError, "%s: a float64 buffer of whole %zd-field records is needed", what, record);
        PyBuffer_Release(view);
        return -1;
    }
    *count = view->len / (record * (Py_ssize_t)sizeof(double));
    return 0;
}

static PyObject *run(PyObject *self, PyObject *args) {
    PyObject *objs[7], *trace_obj = Py_None;
    Py_buffer trace_view = {0};
    if (!PyArg_ParseTuple(args, "OOOOOOO|O:run", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5],
                          &objs[6], &trace_obj))
        return NULL;
    static const char *names[7] = {"engine", "modules", "tpoints", "plant", "instances", "pids", "normals"};
    const Py_ssize_t sizes[7] = {E_SIZE, M_SIZE, T_SIZE, L_SIZE, I_SIZE, P_SIZE, 1};
    Py_buffer views[7];
    Py_ssize_t counts[7];
    int got = 0, status = -1;
    Kernel k;
    memset(&k, 0, sizeof k);
    for (; got < 7; got++)
        if (get_buffer(objs[got], &views[got], sizes[got], names[got], &counts[got]) < 0) goto done;
    if (counts[0] != 1 || counts[6] != NORMALS || counts[2] > 64) {
        PyErr_SetString(PyExc_ValueError, "run: one engine record, 65536 normals and at most 64 points are needed");
        goto done;
    }
    k.eng = views[0].buf; k.mods = views[1].buf; k.tps = views[2].buf; k.plant = views[3].buf;
    k.insts = views[4].buf; k.pids = views[5].buf; k.normals = views[6].buf;
    k.n_mods = counts[1]; k.n_tps = counts[2]; k.n_plant = counts[3]; k.n_insts = counts[4];
    if (trace_obj != Py_None) {
        Py_ssize_t cap;
        if (get_buffer(trace_obj, &trace_view, 1, "trace", &cap) < 0) goto done;
        k.trace = trace_view.buf;
        k.trace_cap = cap;
    }
    k.log_at = calloc(64, sizeof(double *));
    k.log_pv = calloc(64, sizeof(int *));
    k.log_n = calloc(64, sizeof(int));
    k.log_cap = calloc(64, sizeof(int));
    if (!k.log_at || !k.log_pv || !k.log_n || !k.log_cap) { PyErr_NoMemory(); goto done; }
    Py_BEGIN_ALLOW_THREADS
    status = run_span(&k);
    Py_END_ALLOW_THREADS
    if (status < 0) PyErr_NoMemory();
done:
    for (int i = 0; i < 64 && k.log_at; i++) free(k.log_at[i]);
    for (int i = 0; i < 64 && k.log_pv; i++) free(k.log_pv[i]);
    free(k.log_at); free(k.log_pv); free(k.log_n); free(k.log_cap);
    for (int i = 0; i < got; i++) PyBuffer_Release(&views[i]);
    if (trace_view.obj) PyBuffer_Release(&trace_view);
    if (status < 0) return NULL;
    return PyLong_FromSsize_t(k.traced);
}

static PyObject *fields(void) {
#define NAME(name) #name,
    static const char *engine[] = {ENGINE(NAME) NULL}, *module[] = {MODULE(NAME) NULL},
                      *tpoint[] = {TPOINT(NAME) NULL}, *plant[] = {PLANT(NAME) NULL}, *inst[] = {INST(NAME) NULL},
                      *pid[] = {PID(NAME) NULL};
#undef NAME
    static const char *const *lists[] = {engine, module, tpoint, plant, inst, pid};
    static const char *keys[] = {"engine", "modules", "tpoints", "plant", "instances", "pids"};
    PyObject *out = PyDict_New();
    if (!out) return NULL;
    for (int i = 0; i < 6; i++) {
        PyObject *names = PyList_New(0);
        if (!names) { Py_DECREF(out); return NULL; }
        for (const char *const *n = lists[i]; *n; n++) {
            PyObject *s = PyUnicode_FromString(*n);
            if (!s || PyList_Append(names, s) < 0) { Py_XDECREF(s); Py_DECREF(names); Py_DECREF(out); return NULL; }
            Py_DECREF(s);
        }
        PyObject *tuple = PyList_AsTuple(names);
        Py_DECREF(names);
        if (!tuple || PyDict_SetItemString(out, keys[i], tuple) < 0) { Py_XDECREF(tuple); Py_DECREF(out); return NULL; }
        Py_DECREF(tuple);
    }
    return out;
}

static PyMethodDef methods[] = {
    {"run", run, METH_VARARGS,
     "run(engine, modules, tpoints, plant, instances, pids, normals[, trace]): scans until engine.target, in "
     "place; returns the number of scans recorded in trace."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "hil.emulator._kernel",
                                    "The emulator's compiled span kernel (see hil/emulator/kernel.py).", -1, methods};

PyMODINIT_FUNC PyInit__kernel(void) {
    PyObject *m = PyModule_Create(&module);
    if (!m) return NULL;
    PyObject *f = fields();
    if (!f || PyModule_AddObject(m, "FIELDS", f) < 0) { Py_XDECREF(f); Py_DECREF(m); return NULL; }
    return m;
}
