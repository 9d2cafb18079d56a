"""Acoustic modem presets: real modems' published figures as data, each with its source.

``[channel] modem = "NAME"`` fills the ``[channel]`` keys of :data:`FIELDS` from the preset
(band, bit rate, source level, detection threshold, packet overhead, modulation, power by modem
state); a key given in the file overrides the preset's. ``aquasim-py modems`` lists them.

Every figure names where it comes from: a reference of :data:`REFERENCES`, or ``assumed: ...``
with the assumption, where the figure is not published or was not found in the sources
available when the preset was written. Two assumptions recur:

- no datasheet publishes an acquisition SNR: every preset takes ns-3's ``UanPhyGen``
  ``RxThreshold`` default, 10 dB;
- a source level not published is derived from the transmit power, SL = 170.8 + 10 log10(eta
  P_tx) dB re 1 uPa at 1 m (omnidirectional, Urick), with an electro-acoustic efficiency eta =
  0.25 (assumed).

No SimPy, no kernel: plain data.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

__all__ = ["FIELDS", "PRESETS", "REFERENCES", "ModemPreset", "derived_source_level", "preset"]

#: the ``[channel]`` keys a preset sets, with their units (for listings)
FIELDS: Mapping[str, str] = MappingProxyType(
    {
        "frequency_khz": "kHz",
        "bandwidth_khz": "kHz",
        "bitrate_bps": "bit/s",
        "source_level_db": "dB re 1 uPa @ 1 m",
        "snr_threshold_db": "dB",
        "overhead_s": "s",
        "modulation": "",
        "modulation_order": "",
        "coding_gain_db": "dB",
        "tx_power_w": "W",
        "rx_power_w": "W",
        "idle_power_w": "W",
        "sleep_power_w": "W",
    }
)

#: reference key -> citation
REFERENCES: Mapping[str, str] = MappingProxyType(
    {
        "whoi-acomms": "WHOI Acoustic Communications Group, 'Micro-Modem' (packet burst rates: PSK band 5 kHz, "
        "FSK band 4 kHz, rates 80-5400 bit/s, PSK rate 5 ~5000 bit/s, rate 6: 3.25 s signal for a 2.95 s packet), "
        "http://acomms.whoi.edu/micro-modem",
        "ns3-uan": "ns-3 UAN module, src/uan/model/uan-phy-gen.cc (UanPhyGen default modes: FH-FSK 80 bit/s at "
        "22 kHz in 4 kHz, Micro-Modem 2 QPSK 5000 bit/s at 25 kHz in 5 kHz; RxThreshold 10 dB; TxPower 190 dB) "
        "and acoustic-modem-energy-model.cc (WHOI Micro-Modem power: TX 50 W, RX and idle 0.158 W, sleep "
        "0.0058 W), after Freitag et al., 'The WHOI Micro-Modem: an acoustic communications and navigation "
        "system for multiple platforms', OCEANS 2005",
        "evologics-1834": "EvoLogics GmbH, 'S2CR 18/34 Product Information' (datasheet): band 18-34 kHz, range "
        "3500 m, up to 13.9 kbit/s, receive 1.3 W, transmit 2.8 W at the 1 km setting, stand-by 2.5 mW; "
        "www.evologics.de/files/DataSheets/EvoLogics_S2CR_1834_Product_Information.pdf",
        "evologics-717": "EvoLogics GmbH, 'S2CR 7/17 Product Information' (datasheet): band 7-17 kHz, range "
        "8000 m, up to 6.9 kbit/s",
        "benthos-atm900": "Teledyne Benthos, 'ATM-900 Series Acoustic Telemetry Modems, User's Manual', P/N "
        "M-270-26 Rev. D, and the ATM-900 series product description: LF band 9-14 kHz, data rates "
        "140-15 360 bit/s, MFSK and PSK, rate-1/2 convolutional coding, multipath guard period",
        "subnero-silver": "Subnero, 'Silver Edition Modems' (WNC-M25MSS3) technical specifications: up to "
        "15 kbit/s, band 20-32 kHz (carrier 24 kHz, 12 kHz wide), source level 185 dB re 1 uPa @ 1 m rms "
        "(nominal), power < 4 W receiving, < 60 W transmitting (average); subnero.com/products/silver "
        "(source: github.com/subnero1/website-staging products/silver.md @ b9794d8)",
        "urick": "R. J. Urick, 'Principles of Underwater Sound', 3rd ed. (1983): SL = 170.8 + 10 log10 P + DI "
        "dB re 1 uPa at 1 m for P watts of acoustic power",
    }
)

#: electro-acoustic efficiency assumed where a source level is derived from the transmit power
ETA = 0.25


def derived_source_level(tx_power_w: float, eta: float = ETA) -> float:
    """Source level (dB re 1 uPa at 1 m) of an omnidirectional projector fed ``tx_power_w``
    electrical watts at efficiency ``eta``: 170.8 + 10 log10(eta P) (Urick), rounded to 0.1 dB."""
    return round(170.8 + 10.0 * math.log10(eta * tx_power_w), 1)


_THRESHOLD = "assumed: no datasheet publishes an acquisition SNR; ns-3 UanPhyGen's RxThreshold default (ns3-uan)"
_NO_OVERHEAD = "assumed: no preamble or header time published; the bit rate is taken as the packet's whole airtime"
_NO_CODING = "assumed: no coding gain modelled (set coding_gain_db for the modem's code)"


@dataclass(frozen=True)
class ModemPreset:
    """One modem's figures (the ``[channel]`` keys of :data:`FIELDS`) and where each comes from.

    name: the ``[channel] modem`` value. title: the modem and mode. range_m: the nominal range
    a datasheet gives (listed, not applied: the loss model decides who hears whom). sources:
    field -> a :data:`REFERENCES` key (or "KEY: how the figure was read from it"), or
    "assumed: ..." with the assumption."""

    name: str
    title: str
    frequency_khz: float
    bandwidth_khz: float
    bitrate_bps: float
    source_level_db: float
    snr_threshold_db: float
    overhead_s: float
    modulation: str
    modulation_order: int
    coding_gain_db: float
    tx_power_w: float
    rx_power_w: float
    idle_power_w: float
    sleep_power_w: float
    range_m: float | None = None
    sources: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        needed = [k for k in (*FIELDS, "range_m") if getattr(self, k) is not None]
        if self.modulation != "mfsk":  # the order is an M-ary FSK's only
            needed.remove("modulation_order")
        missing = [k for k in needed if k not in self.sources]
        if missing:
            raise ValueError(f"modem preset {self.name!r}: no source for {', '.join(missing)}")
        for k, src in self.sources.items():
            if not (src.partition(": ")[0] in REFERENCES or src.startswith("assumed: ")):
                raise ValueError(f"modem preset {self.name!r}: {k}'s source {src!r} is not a reference")

    def values(self) -> dict[str, Any]:
        """The ``[channel]`` keys this preset sets, with its values."""
        return {k: getattr(self, k) for k in FIELDS}


def _whoi(name: str, title: str, freq: float, band: float, rate: float, mod: str, **src: str) -> ModemPreset:
    return ModemPreset(
        name=name,
        title=title,
        frequency_khz=freq,
        bandwidth_khz=band,
        bitrate_bps=rate,
        source_level_db=190.0,
        snr_threshold_db=10.0,
        overhead_s=0.30,
        modulation=mod,
        modulation_order=2,
        coding_gain_db=0.0,
        tx_power_w=50.0,
        rx_power_w=0.158,
        idle_power_w=0.158,
        sleep_power_w=0.0058,
        sources={
            "source_level_db": "ns3-uan",
            "snr_threshold_db": _THRESHOLD,
            "overhead_s": "whoi-acomms: probe + null, 3.25 - 2.95 s of the PSK rate 6 packet (taken for every "
            "packet type)",
            "coding_gain_db": _NO_CODING,
            "tx_power_w": "ns3-uan",
            "rx_power_w": "ns3-uan",
            "idle_power_w": "ns3-uan",
            "sleep_power_w": "ns3-uan",
            **src,
        },
    )


_DERIVED_SL = f"assumed: derived from tx_power_w, 170.8 + 10 log10({ETA} P_tx) (urick)"
_S2C_RX = 1.3
_S2C_TX = 2.8  # the 1 km setting
_S2C_SLEEP = 0.0025
_S2C_IDLE = 0.010
_S2C_IDLE_SRC = (
    "assumed: 10 mW listening (waiting for a signal in the low-power listen mode); not found in the sources "
    "available (check the datasheet's listen-mode figure)"
)
_S2C_MOD = "assumed: S2C (sweep-spread carrier) is proprietary; modelled as coherent BPSK over the band"


def _s2c(name: str, title: str, freq: float, band: float, rate: float, reach: float, **src: str) -> ModemPreset:
    """An EvoLogics S2C R modem: the family's power figures, with the sources given."""
    return ModemPreset(
        name=name,
        title=title,
        frequency_khz=freq,
        bandwidth_khz=band,
        bitrate_bps=rate,
        source_level_db=derived_source_level(_S2C_TX),
        snr_threshold_db=10.0,
        overhead_s=0.0,
        modulation="bpsk",
        modulation_order=2,
        coding_gain_db=0.0,
        tx_power_w=_S2C_TX,
        rx_power_w=_S2C_RX,
        idle_power_w=_S2C_IDLE,
        sleep_power_w=_S2C_SLEEP,
        range_m=reach,
        sources={
            "source_level_db": _DERIVED_SL,
            "snr_threshold_db": _THRESHOLD,
            "overhead_s": _NO_OVERHEAD,
            "modulation": _S2C_MOD,
            "coding_gain_db": _NO_CODING,
            "idle_power_w": _S2C_IDLE_SRC,
            **src,
        },
    )


PRESETS: Mapping[str, ModemPreset] = MappingProxyType(
    {
        p.name: p
        for p in (
            _whoi(
                "whoi_mm2_fsk",
                "WHOI Micro-Modem 2, FH-FSK (rate 0, 80 bit/s)",
                22.0,
                4.0,
                80.0,
                "bfsk",
                frequency_khz="ns3-uan",
                bandwidth_khz="whoi-acomms",
                bitrate_bps="whoi-acomms",
                modulation="assumed: FH-FSK as non-coherent binary FSK (its frequency hopping and rate-1/2 code "
                "not modelled)",
            ),
            _whoi(
                "whoi_mm2_psk",
                "WHOI Micro-Modem 2, PSK (rate 5, ~5000 bit/s)",
                25.0,
                5.0,
                5000.0,
                "qpsk",
                frequency_khz="ns3-uan",
                bandwidth_khz="whoi-acomms",
                bitrate_bps="whoi-acomms",
                modulation="ns3-uan",
            ),
            _s2c(
                "evologics_s2cr_18_34",
                "EvoLogics S2C R 18/34",
                26.0,
                16.0,
                13900.0,
                3500.0,
                frequency_khz="evologics-1834: the centre of the 18-34 kHz band",
                bandwidth_khz="evologics-1834",
                bitrate_bps="evologics-1834",
                tx_power_w="evologics-1834: the 1 km range setting",
                rx_power_w="evologics-1834",
                sleep_power_w="evologics-1834: stand-by",
                range_m="evologics-1834",
            ),
            _s2c(
                "evologics_s2cr_7_17",
                "EvoLogics S2C R 7/17",
                12.0,
                10.0,
                6900.0,
                8000.0,
                frequency_khz="evologics-717: the centre of the 7-17 kHz band",
                bandwidth_khz="evologics-717",
                bitrate_bps="evologics-717",
                tx_power_w="assumed: the S2C R 18/34's 1 km setting (evologics-1834); the 7/17's own figure was not "
                "found in the sources available",
                rx_power_w="assumed: the S2C R 18/34's (evologics-1834), same S2C electronics; not found for the 7/17",
                sleep_power_w="assumed: the S2C R 18/34's stand-by (evologics-1834); not found for the 7/17",
                range_m="evologics-717",
            ),
            ModemPreset(
                name="benthos_atm9xx_lf",
                title="Teledyne Benthos ATM-9xx, LF band, MFSK 2400 bit/s",
                frequency_khz=11.5,
                bandwidth_khz=5.0,
                bitrate_bps=2400.0,
                source_level_db=derived_source_level(20.0),
                snr_threshold_db=10.0,
                overhead_s=0.0,
                modulation="mfsk",
                modulation_order=4,
                coding_gain_db=0.0,
                tx_power_w=20.0,
                rx_power_w=0.8,
                idle_power_w=0.8,
                sleep_power_w=0.01,
                sources={
                    "frequency_khz": "benthos-atm900: the centre of the LF band",
                    "bandwidth_khz": "benthos-atm900: the LF band",
                    "bitrate_bps": "benthos-atm900: an MFSK rate of the 140-15 360 bit/s range",
                    "source_level_db": _DERIVED_SL,
                    "snr_threshold_db": _THRESHOLD,
                    "overhead_s": _NO_OVERHEAD,
                    "modulation": "benthos-atm900",
                    "modulation_order": "assumed: 4 tones (the manual's MFSK alphabet was not found in the "
                    "sources available)",
                    "coding_gain_db": _NO_CODING,
                    "tx_power_w": "assumed: 20 W (placeholder: the ATM-900 manual's transmit figure was not found "
                    "in the sources available)",
                    "rx_power_w": "assumed: 0.8 W (placeholder: not found in the sources available)",
                    "idle_power_w": "assumed: equal to rx_power_w (placeholder)",
                    "sleep_power_w": "assumed: 10 mW in the low-power state (placeholder: not found in the sources "
                    "available)",
                },
            ),
            ModemPreset(
                name="subnero_m25m",
                title="Subnero WNC-M25MSS3 (silver edition, UnetStack software-defined modem)",
                frequency_khz=26.0,
                bandwidth_khz=12.0,
                bitrate_bps=15000.0,
                source_level_db=185.0,
                snr_threshold_db=10.0,
                overhead_s=0.0,
                modulation="qpsk",
                modulation_order=2,
                coding_gain_db=0.0,
                tx_power_w=60.0,
                rx_power_w=4.0,
                idle_power_w=4.0,
                sleep_power_w=0.05,
                range_m=5000.0,
                sources={
                    "frequency_khz": "subnero-silver: the centre of its 20-32 kHz band (the carrier is quoted as 24 "
                    "kHz), so that the noise is integrated over the band the page gives",
                    "bandwidth_khz": "subnero-silver",
                    "bitrate_bps": "subnero-silver",
                    "source_level_db": "subnero-silver",
                    "snr_threshold_db": _THRESHOLD,
                    "overhead_s": _NO_OVERHEAD,
                    "modulation": "assumed: PSK-OFDM (subnero-silver) as coherent QPSK over the band",
                    "coding_gain_db": _NO_CODING,
                    "tx_power_w": "subnero-silver",
                    "rx_power_w": "subnero-silver",
                    "idle_power_w": "assumed: equal to rx_power_w (a software-defined modem listens with its "
                    "receive chain running; the page gives one receive figure)",
                    "sleep_power_w": "assumed: 50 mW (wake-up over Ethernet, RS232 or acoustic is supported; its "
                    "power is not published)",
                    "range_m": "subnero-silver",
                },
            ),
        )
    }
)


def preset(name: str) -> ModemPreset:
    """The preset called ``name`` (KeyError naming the known ones otherwise)."""
    try:
        return PRESETS[name]
    except KeyError:
        raise KeyError(f"unknown modem {name!r} (known: {', '.join(PRESETS)})") from None
