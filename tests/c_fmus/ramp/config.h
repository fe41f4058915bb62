/* Ramp: a test model on the Reference FMUs' common code (tests/data/reference-fmus/common), built for
 * FMI 2.0 and 3.0, co-simulation and model exchange, by tests/c_fmu_support.py (build_ramp). */
#ifndef config_h
#define config_h

#define MODEL_IDENTIFIER Ramp
#define INSTANTIATION_TOKEN "{6b0c7a52-4a5e-4f1c-9c1e-52a3c7d0ramp}"

#define CO_SIMULATION
#define MODEL_EXCHANGE

#define MAX_CONTINUOUS_STATES 1
#define MAX_EVENT_INDICATORS 1

#define SET_FLOAT64
#define EVENT_UPDATE

#define FIXED_SOLVER_STEP 1e-3
#define DEFAULT_STOP_TIME 1

typedef enum {
    vr_time, vr_x, vr_der_x, vr_s, vr_T_reset, vr_s_after, vr_T_stop, vr_crossings
} ValueReference;

typedef struct {

    double x;          /* the state, an output and the event indicator */
    double s;          /* its slope */
    double T_reset;    /* time event: x = 0 and s = s_after (none when < 0) */
    double s_after;
    double T_stop;     /* time event: the FMU ends the simulation */
    double crossings;  /* events at which x changed domain (x > 0 against x <= 0) since the last event */
    double x_last;     /* x at the last event (or the start) */
    int reset_done;

} ModelData;

#endif /* config_h */
