"""Evaluation of LangCtrl policies: episode logs, paper metrics, statistics, figures, reports."""
