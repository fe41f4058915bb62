/* Ticker: a test model with clocks on the Reference FMUs' common code (tests/data/reference-fmus/common),
 * FMI 3.0 co-simulation (event mode) and model exchange, built by tests/c_fmu_support.py (build_ticker). */
#ifndef config_h
#define config_h

#define MODEL_IDENTIFIER Ticker
#define INSTANTIATION_TOKEN "{3f6a2b1c-0d4e-4c8a-9b7e-5a1d2c3eticker}"

#define CO_SIMULATION
#define MODEL_EXCHANGE

#define SET_FLOAT64
#define EVENT_UPDATE
#define ACTIVATE_CLOCK
#define GET_CLOCK

#define FIXED_SOLVER_STEP 1e-4
#define DEFAULT_STOP_TIME 1

typedef enum {
    vr_time = 0, vr_r = 1, vr_s = 2, vr_o = 3, vr_n = 4, vr_u = 5, vr_y = 6, vr_m = 7, vr_every = 8, vr_t_o = 9
} ValueReference;

typedef struct {

    double n;          /* clocked by r: its ticks */
    double u;          /* a clocked input of s */
    double y;          /* clocked by s: 2 u at s's last tick */
    double m;          /* clocked by o: the rises of o */
    double every;      /* o rises at every this many ticks of r */
    double t_o;        /* o rises at this time too (a time event of the FMU; none when < 0) */
    int r_active, s_active, o_active, o_done;

} ModelData;

#endif /* config_h */
