"""The experiment's report: ``report.json`` (plain data, ``stats.summarize``), ``report.md`` (the
same numbers for people, side by side with the paper) and the figures, in the experiment
directory. Rewritten after every repetition, so a long experiment has a report all along.

report.json: ``task``; ``status`` (repetitions done of all); ``protocol`` (every setting);
``pick_rule`` and ``picked`` (per repetition, with the bound, where it comes from and the
validation's success rates and times);
``training_pick`` (the picks the training success alone makes, where they differ, and their
success rates: what the validation changed); ``bound_sweep`` (per force bound: repetitions with a
pick, how many of those picks are validated, their known and unseen success and commanded force); ``front_size`` (``mean``, ``sd``, per
repetition, and the random search's); ``groups`` (group -> ``known``, ``unseen`` mean success
rates); ``samples`` (their counts); ``mann_whitney`` (baseline -> ``known``, ``unseen``: p of the
picked solutions against it); ``force_and_time`` (group -> ``peak_commanded_force_N``, the
commanded force, ``success_time_s`` over the group's own successes and ``full_episode_time_s``
with a failure counted as the whole episode); ``time_to_success`` (the picked solutions against
the operators' sets, ``paired`` over the worlds where both succeeded and ``full_episode``);
``hypervolume`` (``optimizer``,
``random_search``: final hypervolume per repetition; the curves, the space and reference point);
``wall_time`` (per repetition and kind, seconds); ``sessions``; ``paper`` (the side-by-side rows).
"""

from __future__ import annotations

from mjxskill.runs.atomic_write import write_json, write_text
from mjxskill.evaluation.baselines import stars_of
from mjxskill.experiment.directory import Experiment
from mjxskill.experiment.stats import finished_repetitions, summarize
from mjxskill.experiment.figures import FRONTS, HYPERVOLUME, SUCCESS, plot_fronts, plot_hypervolume
from mjxskill.evaluation.pooled import POOLED_LABELS, plot_pooled, pooled_samples

PAPER_PROTOCOL = (10, 400, 7)  # repetitions, evaluations, worlds (the paper's experiments)


def write_report(exp: Experiment) -> str:
    """Writes report.json, report.md and the figures; returns a line saying where."""
    summary = summarize(exp)
    config = exp.config()
    reps = finished_repetitions(exp, config, exp.protocol())
    if reps:
        plot_fronts(reps, config.objective_names, config.task, exp.path / FRONTS)
        plot_hypervolume(summary["hypervolume"], config.n_init, config.task, exp.path / HYPERVOLUME)
        samples = pooled_samples([r.evaluation for r in reps], [r.pick for r in reps])
        plot_pooled(samples, exp.path / SUCCESS, f"{config.task}: success rate per start configuration, "
                                                 f"{len(reps)} repetitions")
    write_json(exp.path / "report.json", summary)
    write_text(exp.path / "report.md", markdown(summary, figures=bool(reps)))
    s = summary["status"]
    return f"report of {s['repetitions_done']} of {s['repetitions']} repetitions: {exp.path / 'report.md'}"


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:.1f} %"


def _num(v, fmt="{:.3g}") -> str:
    return "-" if v is None else fmt.format(v)


def _p(p) -> str:
    return "-" if p is None else f"{p:.3g} {stars_of(p)}"


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head), *("| " + " | ".join(r) + " |" for r in rows)]


def markdown(s: dict, figures: bool = True) -> str:
    """report.md from the summary ``s`` (``stats.summarize``); ``figures``: link the plots."""
    sections = (_header, _paper_section, _success_section, _picked_section, _confirmation_section, _episodes_section,
                _fronts_section, _hypervolume_section, _wall_time_section, _protocol_section)
    return "\n".join(line for section in sections for line in section(s, figures))


def _header(s: dict, figures: bool) -> list[str]:
    p, st = s["protocol"], s["status"]
    scale = (st["repetitions"], p["budget"], p["worlds"])
    return [f"# Experiment: {s['task']}", "",
            f"{st['repetitions_done']} of {st['repetitions']} repetitions finished"
            + ("." if st["repetitions_done"] == st["repetitions"] else " (the report covers the finished ones)."),
            f"Protocol {scale[0]} repetitions x {scale[1]} evaluations x {scale[2]} worlds"
            + (f", smaller than the paper's {PAPER_PROTOCOL[0]} x {PAPER_PROTOCOL[1]} x {PAPER_PROTOCOL[2]}."
               if any(a < b for a, b in zip(scale, PAPER_PROTOCOL)) else ", the paper's."), ""]


def _paper_section(s: dict, figures: bool) -> list[str]:
    lines = ["## Side by side with the paper", ""]
    rows = []
    for row in s["paper"]:
        if "ours_known" in row:
            ours = f"{_pct(row['ours_known'])} known, {_pct(row['ours_unseen'])} unseen"
        elif row["unit"] == "fraction":
            ours = f"{_pct(row['ours'])} ({_detail(row['detail'])})"
        else:
            ours = _num(row["ours"], "{:.1f}")
        paper = "-" if row["paper"] is None else (_pct(row["paper"]) if row["unit"] == "fraction" else f"{row['paper']:g}")
        rows.append([row["quantity"], paper, ours])
    lines += _table(["quantity", "paper", "ours"], rows)
    t = s["time_to_success"]
    lines += ["", "The paper's success rates are the real robot's over known and unseen start configurations; ours "
              "are simulated, per start configuration group. The operators' sets are illustrative: examples "
              "invented for this repository (the scenario's manual_parameters, where the YAML says how they were "
              "chosen), not the paper's operators', whose sets are unpublished.", "",
              "Times to success compare like with like. Paired: the picked solution and an operator set on the "
              "worlds where both succeeded (each such pair once; the paper's 18.1 % compares successful insertions). "
              f"Full episode: every world, one that did not succeed counted as the whole {t['episode_seconds']:g} s "
              "episode, so failing costs time. The mean over each group's own successes alone (report.json's "
              "success_time_s) is not compared: the more a group succeeds, the more slow successes it counts.", ""]
    if t["repetitions"] < s["status"]["repetitions_done"]:
        lines += [f"Per-world times are in {t['repetitions']} of {s['status']['repetitions_done']} repetitions' "
                  "evaluations (the others were written before they were kept); the time rows cover those. Moving a "
                  "repetition's evaluation/evaluation.json aside and evaluating the experiment again adds them "
                  "(the same worlds: the same success rates).", ""]
    return lines


def _detail(detail: dict) -> str:
    """A row's measured values: ``picked_s`` -> "picked 4.1 s"; ``paired_worlds`` -> "3 paired worlds"."""
    out = []
    for key, value in detail.items():
        what, unit = key.rsplit("_", 1)
        out.append(f"{_num(value)} {what} {unit}" if unit == "worlds" else f"{what} {_num(value)} {unit}")
    return ", ".join(out)


def _success_section(s: dict, figures: bool) -> list[str]:
    p = s["protocol"]
    lines = ["## Success rates", ""] + ([f"![success rates]({SUCCESS})", ""] if figures else [])
    rows = []
    for g, m in s["groups"].items():
        tests = s["mann_whitney"].get(g, {})
        n = s["samples"][g]
        rows.append([POOLED_LABELS[g], _pct(m["known"]), _pct(m["unseen"]), f"{n['known']} + {n['unseen']}",
                     _p(tests.get("known")), _p(tests.get("unseen"))])
    lines += _table(["group", "known", "unseen", "samples (known + unseen)", "picked vs group, known",
                     "picked vs group, unseen"], rows)
    lines += ["", "Mann-Whitney U, two-sided, stars at the paper's levels: * p < 0.1, ** p < 0.05, *** p < 0.01, "
              "**** p < 0.001. A sample is one success rate per (repetition, candidate, start configuration), each over "
              f"{p['per_config']} worlds: the picked group has one candidate per repetition, so R repetitions give R x C "
              "samples (C start configurations); one sample per repetition would be too few. Samples of a repetition share "
              "its worlds and are not independent.", ""]
    return lines + _finding(s)


def _picked_section(s: dict, figures: bool) -> list[str]:
    lines = ["## Picked solutions", "", f"Rule: {s['pick_rule']}.", ""]
    if "race" in s:
        return lines + _raced_picks(s)
    names = list(s["protocol"]["parameters"])
    validated = s.get("training_pick", {}).get("validated", False)
    rows = [[str(r["seed"]), _num(r["pareto_row"], "{}"), _num(r["bound_N"], "{:.2f} N")]
            + ([_num(r["parameters"][n], "{:.4g}") for n in names] + [_pct(r["training_success"])]
               + ([_pct(r["validation_success"])] if validated else [])
               + [_num(r["training_peak_commanded_force_N"], "{:.2f}"), _pct(r["known"]), _pct(r["unseen"])]
               if r["pareto_row"] is not None else
               ["no Pareto solution within the bound"] + [""] * (len(names) + 3 + validated))
            for r in s["picked"]]
    lines += _table(["seed", "Pareto row", "bound", *(n.split(".")[-1] for n in names), "training success",
                     *(["validation success"] if validated else []), "commanded force [N]", "known", "unseen"], rows)
    return lines + [""] + _validation_effect(s) + _sweep(s)


def _raced_picks(s: dict) -> list[str]:
    """The picks of raced repetitions: parameters, training success over the worlds the run
    pooled, race success, and the evaluation's and the confirmation's success rates."""
    names = list(s["protocol"]["parameters"])
    confirmed = "confirmation" in s
    races = {r["seed"]: r for r in s["race"]}
    rows = []
    for r in s["picked"]:
        race = races.get(r["seed"], {})
        plan = ", ".join(f"{x['contenders']} x {x['worlds']}" for x in race.get("rounds", []))
        if r["pareto_row"] is None:
            rows.append([str(r["seed"]), "-", "no Pareto solution within the bound"] + [""] * (len(names) + 5 + 2 * confirmed))
            continue
        rows.append([str(r["seed"]), str(r["pareto_row"]), f"{race.get('contenders', '-')} ({plan})"]
                    + [_num(r["parameters"][n], "{:.4g}") for n in names]
                    + [f"{_pct(r['training_success'])} of {r.get('training_worlds', '-')}",
                       f"{r.get('race_successes', '-')}/{r.get('race_worlds', '-')}",
                       _num(r["training_peak_commanded_force_N"], "{:.2f}"), _pct(r["known"]), _pct(r["unseen"])]
                    + ([_pct(r.get("confirmed_known")), _pct(r.get("confirmed_unseen"))] if confirmed else []))
    head = ["seed", "Pareto row", "contenders (rounds: contenders x worlds)", *(n.split(".")[-1] for n in names),
            "training success (worlds)", "race success", "commanded force [N]", "evaluation known", "evaluation unseen",
            *(["confirmed known", "confirmed unseen"] if confirmed else [])]
    per = s["protocol"]["per_config"]
    return _table(head, rows) + ["", f"Evaluation: {per} worlds per start configuration (the paper's evaluation, every "
                                 "Pareto solution). Confirmed: the confirmation's worlds (next section).", ""]


def _confirmation_section(s: dict, figures: bool) -> list[str]:
    """The pick and the operators' sets in the confirmation's worlds, per repetition and pooled."""
    c = s.get("confirmation")
    if not c:
        return []
    names = list(c["pooled"])
    lines = ["## Confirmation: the pick and the operators' sets in many worlds", "",
             f"Every repetition rolls its pick and the operators' illustrative sets out in the same {c['per_config']} "
             f"fresh worlds from each of the {c['configs']} start configurations (known and unseen), drawn from the "
             "repetition's seed on a stream of their own, apart from the training, race and evaluation worlds.", ""]
    rows = [[str(e["seed"])] + [f"{_pct(e['candidates'][n]['known'])} / {_pct(e['candidates'][n]['unseen'])}"
                                if n in e["candidates"] else "-" for n in names] for e in c["repetitions"]]
    lines += _table(["seed", *(f"{n} known / unseen" for n in names)], rows)
    pooled = [[n, _pct(p["known"]), _pct(p["unseen"]), _pct(p["lowest_unseen"]),
               _num(p["full_episode_time_s"], "{:.2f} s"), _num(p["peak_commanded_force_N"], "{:.2f} N")]
              for n, p in c["pooled"].items()]
    lines += ["", "Pooled over the repetitions:", ""]
    lines += _table(["candidate", "known", "unseen", "lowest repetition, unseen",
                     "time to success (failure = full episode)", "commanded force"], pooled)
    return lines + [""]


def _episodes_section(s: dict, figures: bool) -> list[str]:
    """The episodes each repetition's optimizer run and pick spent, against the paper's budget."""
    e = s.get("episodes")
    if not e:
        return []
    p = s["protocol"]
    rows = [[str(r["seed"]), str(r["training"]), str(r["replication"]), str(r["race"]), str(r["total"]),
             f"{r['of_paper_budget']:.3f}"] for r in e]
    return (["## Episodes spent", ""]
            + _table(["seed", "new parameter sets", "rolled out again", "race", "total",
                      f"of the paper's {p['budget']} x {p['worlds']}"], rows)
            + ["", "Training episodes (new sets and those rolled out again) are the run's budget x worlds; the race "
               "adds its share. The evaluation and the confirmation measure the pick for this report and are not "
               "counted: a user does not run them.", ""])


def _sweep(s: dict) -> list[str]:
    """How the picked success changes with the force bound (``stats.bound_sweep``)."""
    sweep = s.get("bound_sweep") or []
    if not sweep:
        return []
    validated = sweep[0]["validated"] is not None
    n = s["status"]["repetitions_done"]
    rows = [[f"{r['bound_N']:g} N" + (" (used)" if r["used"] else ""), f"{r['repetitions_with_pick']} of {n}"]
            + ([f"{r['validated']} of {n}"] if validated else [])
            + [_pct(r["known"]), _pct(r["unseen"]), _num(r["mean_commanded_force_N"], "{:.2f} N")] for r in sweep]
    lines = ["### The picked success against the force bound", ""]
    lines += _table(["bound", "repetitions with a pick", *(["picks validated"] if validated else []), "known", "unseen",
                     "mean commanded force of the picks"], rows)
    note = ("From the training fronts and the evaluation, which holds every Pareto solution: no rollout is made. ")
    if validated:
        note += ("Where a repetition's validation did not roll out the contenders at a bound, its pick there is by "
                 "training success alone (the 'picks validated' column counts the others); validating them would take "
                 f"{s['protocol']['validation_candidates']} x {s['protocol']['validation_per_config']} episodes per known "
                 "start configuration and repetition more.")
    return lines + ["", note, ""]


def _fronts_section(s: dict, figures: bool) -> list[str]:
    f = s["front_size"]
    return ["## Pareto fronts", ""] + ([f"![Pareto fronts]({FRONTS})", ""] if figures else []) + [
        f"Front size: optimizer {_num(f['mean'], '{:.2f}')} +- {_num(f['sd'], '{:.2f}')} (mean +- sd over "
        f"repetitions; per seed {f['per_repetition']}); random search {_num(f['random_search']['mean'], '{:.2f}')} "
        f"+- {_num(f['random_search']['sd'], '{:.2f}')} ({f['random_search']['per_repetition']}).", ""]


def _hypervolume_section(s: dict, figures: bool) -> list[str]:
    hv = s["hypervolume"]
    lines = ["## Hypervolume", ""] + ([f"![hypervolume]({HYPERVOLUME})", ""] if figures else [])
    if hv["optimizer"]:
        lines += _table(["seed", "optimizer", "random search"],
                        [[str(r["seed"]), f"{a:.4f}", f"{b:.4f}"] for r, a, b in zip(s["picked"], hv["optimizer"], hv["random_search"])])
        lines += ["", f"Final hypervolume in the {hv['space']}; reference point {hv['reference_point']}. Optimizer vs "
                  f"random search, Mann-Whitney U over the repetitions: p = {_p(hv['mann_whitney_p_final'])} (with R "
                  "repetitions per side the smallest possible two-sided p is 2 / C(2R, R)).", ""]
    return lines


def _wall_time_section(s: dict, figures: bool) -> list[str]:
    lines = ["## Wall time", ""]
    raced = any(k["optimizer"].get(f) is not None for k in s["wall_time"].values() for f in ("race_seconds", "confirm_seconds"))
    picking = ("race_seconds", "confirm_seconds") if raced else ("validate_seconds",)
    rows = []
    for seed, kinds in s["wall_time"].items():
        o, r = kinds["optimizer"], kinds["random_search"]
        total = sum(e.get(k, 0.0) for e, k in ((o, "train_seconds"), (r, "train_seconds"), (o, "evaluate_seconds"),
                                                *((o, f) for f in picking)))
        rows.append([seed, _secs(o, "train_seconds"), _secs(o, "simulation_seconds"), _secs(r, "train_seconds"),
                     _num(o.get("evaluate_seconds"), "{:.0f} s"), *(_num(o.get(f), "{:.0f} s") for f in picking),
                     f"{total:.0f} s"])
    lines += _table(["seed", "optimizer run (evaluations)", "of it simulation", "random search run", "evaluation",
                     *(["race", "confirmation"] if raced else ["validation"]), "repetition"], rows)
    sessions = s["sessions"]
    return lines + ["", f"{len(sessions)} session(s); start-up (planning, engine start, compilation) "
                    + ", ".join(f"{x['startup_seconds']:.0f} s ({x['engine']}, {x['cpus']} CPUs)" for x in sessions)
                    + ". Times are this machine's, shared with other work while they ran.", ""]


def _protocol_section(s: dict, figures: bool) -> list[str]:
    p = s["protocol"]
    lines = ["## Protocol", ""]
    lines += _table(["setting", "value"], [[k, f"`{v}`"] for k, v in p.items() if k != "parameters"])
    return lines + ["", "Parameters: " + ", ".join(f"{n} in [{v['bounds'][0]:g}, {v['bounds'][1]:g}] {v['unit']}"
                                                   for n, v in p["parameters"].items()) + ".", ""]


def _validation_effect(s: dict) -> list[str]:
    """What the validation changed: the picks the training success alone would have made."""
    t = s.get("training_pick", {})
    if not t.get("validated"):
        return []
    if not t["changed"]:
        return ["The validation picked what the training success alone picks in every repetition.", ""]
    seeds = ", ".join(f"seed {c['seed']}: row {c['validated_row']} instead of {c['training_row']}" for c in t["changed"])
    g, mine = t["groups"], s["groups"].get("picked", {})
    return [f"The validation changed the pick in {len(t['changed'])} of {len(s['picked'])} repetitions ({seeds}). "
            f"The training success alone would have picked solutions that reach {_pct(g.get('known'))} known, "
            f"{_pct(g.get('unseen'))} unseen, against {_pct(mine.get('known'))} and {_pct(mine.get('unseen'))} for "
            "the validated picks.", ""]


def _secs(entry: dict, field: str) -> str:
    if field not in entry:
        return "-"
    return f"{entry[field]:.0f} s ({entry.get(field + '_evaluations', 0)})"


def _finding(s: dict) -> list[str]:
    """The sentence the issue asks for: do the picked solutions beat random sets and planner-only
    on the unseen configurations with p < 0.05? As measured."""
    out = []
    for baseline in ("random", "planner"):
        t = s["mann_whitney"].get(baseline, {}).get("unseen")
        if t is None:
            continue
        mp, mb = s["groups"]["picked"]["unseen"], s["groups"][baseline]["unseen"]
        better = mp is not None and mb is not None and mp > mb
        verdict = "beat" if (t < 0.05 and better) else "did not beat"
        out.append(f"On the unseen start configurations the picked solutions {verdict} {POOLED_LABELS[baseline]} "
                   f"at p < 0.05 ({_pct(mp)} vs {_pct(mb)}, p = {t:.3g}).")
    return (["**Finding.** " + " ".join(out), ""]) if out else []


__all__ = ["PAPER_PROTOCOL", "markdown", "write_report"]
