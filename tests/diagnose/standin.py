"""A toy plant for testing the diagnosis pipeline ONLY (never used for results).

It implements leveler.diagnose.model.Simulator with crude SI dynamics (one
pressure, a hysteretic platform, an on-off band controller) and two effects,
`leak` and `sensor_lag`, so the pipeline's plumbing (phases, fitting,
ranking, report, CLI) can be tested before and independently of the C plant.
A third, `area` (its offset only: the spring's effective area scaled), raises
the steady pressure a load needs much as a pressure offset does: a look-alike
of `sensor_lag` for the tests of the ranked second effect.
"""
import numpy as np

from leveler.diagnose.model import CLOSED_LOOP, Simulator, Trace

PA = 101325.0
AREA = 0.0078
VOL = 4.4e-3
BAND = (0.39624, 0.40132)


class StandIn(Simulator):
    def configs(self):
        return ["toy"]

    def _run(self, t, load, commands, leak, tau_p, p_offset, closed, area=AREA):
        n = len(t)
        y, p2 = 0.3975, PA + load[0] / area
        lag = p2
        out = {k: np.empty(n) for k in ("height_m", "p_spring_pa", "p_pipe_pa", "p_acc_pa")}
        cmd = {k: np.zeros(n, dtype=np.int32) for k in ("compressor", "spring_valve", "vent_valve", "acc_valve")}
        comp = sol = vent = 0
        for i in range(n):
            dt = t[i] - t[i - 1] if i else 0.0
            if closed:
                comp = int(y < BAND[0])
                vent = int(y > BAND[1])
                sol = comp | vent
            else:
                comp, sol, vent = commands["compressor"][i], commands["spring_valve"][i], commands["vent_valve"][i]
            cmd["compressor"][i], cmd["spring_valve"][i], cmd["vent_valve"][i] = comp, sol, vent
            for _ in range(2):
                h = dt / 2
                f = (p2 - PA) * area - load[i]
                band = 400.0
                v = 0.0 if abs(f) < band else (f - np.sign(f) * band) / 2.0e5
                q = 5.0e-5 * comp * sol - 1.3e-10 * vent * sol * (p2 - PA) - leak * (p2 - PA)
                p2 += h * 1.1 * p2 / VOL * (q - area * v)
                y = min(max(y + h * v, 0.3), 0.5)
                lag += h * (p2 - lag) / tau_p if tau_p > 1e-3 else (p2 - lag)
            if tau_p <= 1e-3:
                lag = p2
            out["height_m"][i] = y
            out["p_spring_pa"][i] = lag + p_offset
            out["p_pipe_pa"][i] = np.nan
            out["p_acc_pa"][i] = np.nan
        return out, cmd

    def simulate(self, config, run, effect, params, mode):
        names = (effect or "").split("+")    # a pair "leak+sensor_lag" runs both
        leak = params.get("leak_area_m2", 0.0) * 1e-4 if "leak" in names else 0.0
        tau = params.get("tau_pressure_s", 0.0) if "sensor_lag" in names else 0.0
        off = params.get("p_offset_pa", 0.0) if "sensor_lag" in names else 0.0
        area = AREA * (1.0 + params.get("area_offset_rel", 0.0)) if "area" in names else AREA
        sig, cmd = self._run(run.t_s, run.load_n, run.commands, leak, tau, off, mode == CLOSED_LOOP, area)
        return Trace(run.t_s, sig, cmd)

    def generate(self, config, t_s, load_n, truth_effect, truth_params, seed):
        class R:  # minimal run
            pass
        r = R()
        r.t_s, r.load_n, r.commands = t_s, load_n, {}
        return self.simulate(config, r, truth_effect, truth_params, CLOSED_LOOP)
